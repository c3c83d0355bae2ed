"""Procedural solid textures: Perlin noise (noise.py) and Hart et al. 1999's parameterised model (hart.py)."""
