"""Spectral integration for diffraction shading: CIE 1931 matching functions, D65 light, XYZ -> sRGB.

Stam's BRDF is a function of wavelength; a pixel's colour is its integral against the CIE 1931 2°
colour-matching functions (colour-science's tables) under the light's spectrum. The light is CIE D65, so
that a flat mirror in its specular direction (relative reflectance 1 at every wavelength) comes out as
linear sRGB (1, 1, 1): the weights are normalised so that the white's Y is 1. XYZ -> linear sRGB uses the
D65 matrix of IEC 61966-2-1 (DESIGN.md erratum: not CIE RGB or Adobe RGB).

`spectral_weights(step_nm)` gives the wavelengths (µm) from 380 to 780 nm and their XYZ weights
(CMF x D65 x step, white Y = 1); the shader reads them from a float texture.
"""

from __future__ import annotations

import numpy as np

from prefilter import PrefilterError

LAMBDA_MIN_NM = 380.0
LAMBDA_MAX_NM = 780.0

# IEC 61966-2-1 (sRGB), D65 white: linear RGB from XYZ
SRGB_FROM_XYZ = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def spectral_weights(step_nm: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """(wavelengths in µm (n,), XYZ weights (n, 3)) over 380-780 nm every `step_nm`; the weights of a
    spectrally flat reflectance of 1 sum to D65's XYZ with Y = 1."""
    import colour

    if not 0.1 <= step_nm <= 50.0:
        raise PrefilterError(f"spectral step {step_nm} nm: expected 0.1 to 50 nm")
    count = int(round((LAMBDA_MAX_NM - LAMBDA_MIN_NM) / step_nm)) + 1
    nm = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, count)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    xyz = np.stack([np.interp(nm, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)], axis=1)
    light = np.interp(nm, d65.wavelengths, d65.values)
    weights = xyz * light[:, None]
    weights /= weights[:, 1].sum()
    return nm / 1000.0, weights


def xyz_to_srgb(xyz: np.ndarray) -> np.ndarray:
    """Linear sRGB (D65) from CIE XYZ, (..., 3)."""
    return np.asarray(xyz) @ SRGB_FROM_XYZ.T
