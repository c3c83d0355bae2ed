"""Colour tables and their prefiltered forms (Hart et al. 1999): point, MIP-mapped and summed-area lookups."""
