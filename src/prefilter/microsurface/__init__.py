"""Gaussian microsurfaces: Heitz et al. 2013/2014 §3, §5–§8."""
