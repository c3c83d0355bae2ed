"""Image error metrics against the supersampled reference, over pixels fully covered by the surface.

- FLIP: Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström, Fairchild, "FLIP: A Difference Evaluator
  for Alternating Images", Proc. ACM Comput. Graph. Interact. Tech. 3(2), 2020. LDR-FLIP through the
  `flip_evaluator` package at its default 67 pixels per degree (0.7 m from a 0.7 m wide, 3840 px display).
- ΔE2000: Sharma, Wu, Dalal, "The CIEDE2000 Color-Difference Formula: Implementation Notes,
  Supplementary Test Data, and Mathematical Observations", Color Res. Appl. 30(1), 2005; via colour-science,
  linear sRGB -> XYZ (IEC 61966-2-1 matrix, D65) -> CIELAB with the display white RGB (1, 1, 1) as
  reference white (L = 100, a = b = 0).
- RMSE: in linear RGB, over masked pixels and the three channels.

FLIP and ΔE2000 judge the displayed image: linear values are clipped to [0, 1] first. RMSE is unclipped.
FLIP filters spatially (its contrast-sensitivity and feature filters span several pixels), so `compare`
gives the test image the reference's values off the mask before evaluating it: the errors of pixels that
are not fully covered (silhouettes, which are geometry aliasing, and the background) neither count nor
leak into their covered neighbours.
"""

from __future__ import annotations

import numpy as np

from prefilter.images import linear_to_srgb


def _check_pair(test: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(test)
    r = np.asarray(reference)
    if t.shape != r.shape or t.ndim != 3 or t.shape[2] != 3:
        raise ValueError(f"test and reference must both be (H, W, 3); got {t.shape} and {r.shape}")
    return t, r


def _check_mask(mask: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    m = np.asarray(mask)
    if m.dtype != np.bool_:
        raise ValueError(f"mask must be a boolean array, got dtype {m.dtype}")
    if m.shape != tuple(shape[:2]):
        raise ValueError(f"mask shape {m.shape} does not match image shape {tuple(shape[:2])}")
    if not m.any():
        raise ValueError("mask is empty: no pixel is fully covered by the surface")
    return m


def _display_srgb(linear_rgb: np.ndarray) -> np.ndarray:
    lin = np.clip(np.nan_to_num(np.asarray(linear_rgb, dtype=np.float64), nan=0.0), 0.0, 1.0)
    return np.ascontiguousarray(linear_to_srgb(lin), dtype=np.float32)


def flip_map(test: np.ndarray, reference: np.ndarray, ppd: float | None = None) -> np.ndarray:
    """Per-pixel LDR-FLIP error in [0, 1], (H, W) float32. `ppd` overrides the package's 67 pixels/degree."""
    import flip_evaluator

    t, r = _check_pair(test, reference)
    parameters: dict = {}
    if ppd is not None:
        if not ppd > 0:  # flip_evaluator calls sys.exit on a non-positive ppd; fail politely instead
            raise ValueError(f"ppd must be positive, got {ppd}")
        parameters["ppd"] = float(ppd)
    error, _, _ = flip_evaluator.evaluate(
        _display_srgb(r),
        _display_srgb(t),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        computeMeanError=False,
        parameters=parameters,
    )
    return np.asarray(error, dtype=np.float32).reshape(t.shape[:2])


def delta_e2000_lab(lab_1: np.ndarray, lab_2: np.ndarray) -> np.ndarray:
    """CIEDE2000 between CIELAB arrays (..., 3) with L in [0, 100] (kL = kC = kH = 1)."""
    import colour

    with colour.domain_range_scale("reference"):
        return np.asarray(colour.difference.delta_E_CIE2000(lab_1, lab_2), dtype=np.float64)


def linear_srgb_to_lab(linear_rgb: np.ndarray) -> np.ndarray:
    """Linear sRGB (..., 3) -> XYZ (D65, Y = 1 for white) -> CIELAB, white RGB (1, 1, 1) -> (100, 0, 0)."""
    import colour

    srgb = colour.RGB_COLOURSPACES["sRGB"]
    matrix = srgb.matrix_RGB_to_XYZ  # IEC 61966-2-1 (D65)
    xyz = np.asarray(linear_rgb, dtype=np.float64) @ matrix.T
    # White point = XYZ of RGB (1, 1, 1), so display white is exactly L = 100, a = b = 0 (the rounded IEC
    # matrix and the D65 chromaticity (0.3127, 0.3290) disagree in the fifth decimal).
    white_xy = colour.XYZ_to_xy(matrix @ np.ones(3))
    with colour.domain_range_scale("reference"):
        return np.asarray(colour.XYZ_to_Lab(xyz, illuminant=white_xy), dtype=np.float64)


def delta_e2000_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-pixel CIEDE2000 between two linear-RGB images (clipped to [0, 1]), (H, W) float32."""
    t, r = _check_pair(test, reference)
    lab_t = linear_srgb_to_lab(np.clip(np.nan_to_num(t.astype(np.float64), nan=0.0), 0.0, 1.0))
    lab_r = linear_srgb_to_lab(np.clip(np.nan_to_num(r.astype(np.float64), nan=0.0), 0.0, 1.0))
    return delta_e2000_lab(lab_t, lab_r).astype(np.float32)


def rmse(test: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """Root-mean-square difference in linear RGB over the masked pixels and all three channels."""
    t, r = _check_pair(test, reference)
    m = _check_mask(mask, t.shape)
    d = t[m].astype(np.float64) - r[m].astype(np.float64)
    return float(np.sqrt(np.mean(d * d)))


def compare(test: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> dict:
    """Errors of `test` against `reference` over `mask` (boolean (H, W), pixels fully covered by the surface).

    Returns {"flip": mean FLIP, "delta_e": mean ΔE2000, "rmse": RMSE, "flip_map": (H, W) float32}.
    FLIP is evaluated on the whole image with the reference's values off the mask (see the module
    docstring) and averaged over the mask. Raises ValueError if the mask is empty or shapes disagree.
    """
    t, r = _check_pair(test, reference)
    m = _check_mask(mask, t.shape)
    fmap = flip_map(np.where(m[..., None], t, r), r)
    de = delta_e2000_map(t, r)
    return {
        "flip": float(np.mean(fmap[m], dtype=np.float64)),
        "delta_e": float(np.mean(de[m], dtype=np.float64)),
        "rmse": rmse(t, r, m),
        "flip_map": fmap,
    }
