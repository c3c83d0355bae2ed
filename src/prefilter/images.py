"""Image I/O and presentation: the sRGB transfer curve, PNG/EXR files, false colour and labelled strips.

Images are float32 linear-RGB arrays (H, W, 3), top row first.
- sRGB curve: IEC 61966-2-1:1999 piecewise OETF/EOTF (breakpoints 0.0031308 linear / 0.04045 encoded).
- `.png`: 8-bit sRGB-encoded (imageio); metadata as JSON in an iTXt chunk named `prefilter`.
- `.exr`: float32 linear RGB, ZIP compression (OpenEXR 3.x package); metadata as JSON in the string
  header attribute `prefilter`.
Writes are atomic: a temporary file in the destination directory, then os.replace.
- `box_downsample`: exact area-weighted reduction to a smaller size (a render at a fractional scale seen
  through the same box pixels).
"""

from __future__ import annotations

import json
import os
import secrets
from pathlib import Path
from typing import Any

import numpy as np

from prefilter import PrefilterError
from prefilter.image_data import PNG_SIGNATURE, one_line

IMAGE_EXTENSIONS = (".png", ".exr")
METADATA_KEY = "prefilter"
LABEL_BACKGROUND = 48  # sRGB 8-bit grey of label bars and gaps
LABEL_FOREGROUND = 255


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """sRGB OETF (IEC 61966-2-1): linear -> encoded. No clipping; the linear segment covers x <= 0.0031308."""
    x = np.asarray(x, dtype=np.float64)
    power = 1.055 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4) - 0.055
    return np.where(x <= 0.0031308, 12.92 * x, power)


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """sRGB EOTF (IEC 61966-2-1): encoded -> linear. No clipping; the linear segment covers x <= 0.04045."""
    x = np.asarray(x, dtype=np.float64)
    power = np.power((np.maximum(x, 0.04045) + 0.055) / 1.055, 2.4)
    return np.where(x <= 0.04045, x / 12.92, power)


def _as_rgb(linear_rgb: np.ndarray, path: Path) -> np.ndarray:
    a = np.asarray(linear_rgb)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] == 0 or a.shape[1] == 0:
        raise PrefilterError(f"{path}: expected an (H, W, 3) image, got shape {a.shape}")
    return a


def _unsupported(path: Path, ext: str) -> PrefilterError:
    valid = ", ".join(IMAGE_EXTENSIONS)
    return PrefilterError(f"{path}: unsupported image extension {ext or '(none)'!r}; use one of {valid}")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"metadata value of type {type(o).__name__} is not JSON-serialisable")


def _encode_png8(linear_rgb: np.ndarray) -> np.ndarray:
    lin = np.nan_to_num(np.asarray(linear_rgb, dtype=np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    return np.round(linear_to_srgb(np.clip(lin, 0.0, 1.0)) * 255.0).astype(np.uint8)


def _write_png(tmp: Path, rgb: np.ndarray, meta_json: str | None) -> None:
    import imageio.v3 as iio
    from PIL.PngImagePlugin import PngInfo

    kwargs: dict[str, Any] = {}
    if meta_json is not None:
        info = PngInfo()
        info.add_itxt(METADATA_KEY, meta_json)
        kwargs["pnginfo"] = info
    iio.imwrite(tmp, _encode_png8(rgb), extension=".png", **kwargs)


def _write_exr(tmp: Path, rgb: np.ndarray, meta_json: str | None) -> None:
    import OpenEXR

    header: dict[str, Any] = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if meta_json is not None:
        header[METADATA_KEY] = meta_json
    pixels = np.ascontiguousarray(rgb, dtype=np.float32)
    OpenEXR.File(header, {"RGB": pixels}).write(str(tmp))


_WRITERS = {".png": _write_png, ".exr": _write_exr}


def write_image(path: str | os.PathLike, linear_rgb: np.ndarray, metadata: dict | None = None) -> Path:
    """Write a linear-RGB image; the format follows the extension (.png: 8-bit sRGB, .exr: float32 linear).

    `metadata` (a JSON-serialisable dict) is stored in the file and returned by `read_image`. The write is
    atomic: on any failure no partial file is left at `path` or beside it. Parent directories are created.
    Returns the path written.
    """
    path = Path(path)
    ext = path.suffix.lower()
    writer = _WRITERS.get(ext)
    if writer is None:
        raise _unsupported(path, ext)
    rgb = _as_rgb(linear_rgb, path)
    meta_json = None
    if metadata is not None:
        meta_json = json.dumps(metadata, sort_keys=True, default=_json_default)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp{ext}")
    try:
        writer(tmp, rgb, meta_json)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _read_png(path: Path) -> tuple[np.ndarray, dict]:
    import imageio.v3 as iio

    with open(path, "rb") as f:  # else imageio tries every plugin it has on the file, and says so at length
        if f.read(len(PNG_SIGNATURE)) != PNG_SIGNATURE:
            raise PrefilterError(f"{path}: not a PNG file")
    a = iio.imread(path)
    if a.dtype == np.uint8:
        enc = a.astype(np.float64) / 255.0
    elif a.dtype == np.uint16:
        enc = a.astype(np.float64) / 65535.0
    else:
        raise PrefilterError(f"{path}: unsupported PNG sample type {a.dtype}")
    if enc.ndim == 2:
        enc = np.repeat(enc[:, :, None], 3, axis=2)
    elif enc.shape[2] in (1, 2):  # grey, grey+alpha
        enc = np.repeat(enc[:, :, :1], 3, axis=2)
    else:
        enc = enc[:, :, :3]
    text = iio.immeta(path).get(METADATA_KEY)
    return srgb_to_linear(enc).astype(np.float32), (json.loads(text) if text else {})


def _read_exr(path: Path) -> tuple[np.ndarray, dict]:
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        channels = f.channels()
        header = dict(f.header())  # the File's own header dict is emptied when the File is closed
        if "RGB" in channels:
            rgb = channels["RGB"].pixels
        elif "RGBA" in channels:
            rgb = channels["RGBA"].pixels[:, :, :3]
        elif all(c in channels for c in "RGB"):
            rgb = np.stack([channels[c].pixels for c in "RGB"], axis=2)
        elif "Y" in channels:
            rgb = np.repeat(channels["Y"].pixels[:, :, None], 3, axis=2)
        else:
            raise PrefilterError(f"{path}: no RGB or Y channels (found {', '.join(sorted(channels))})")
        rgb = np.array(rgb, dtype=np.float32)
    text = header.get(METADATA_KEY)
    return rgb, (json.loads(text) if isinstance(text, str) and text else {})


def read_image(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """Read a .png or .exr written by `write_image`: (linear float32 (H, W, 3), metadata dict)."""
    path = Path(path)
    ext = path.suffix.lower()
    readers = {".png": _read_png, ".exr": _read_exr}
    if ext not in readers:
        raise _unsupported(path, ext)
    if not path.is_file():
        raise PrefilterError(f"{path}: no such image file")
    try:
        return readers[ext](path)
    except PrefilterError:
        raise
    except Exception as exc:  # imageio and OpenEXR raise many kinds (OSError, RuntimeError, ValueError)
        raise PrefilterError(f"{path}: cannot read as {ext[1:].upper()} ({one_line(exc)})") from None


def _box_weights(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in): output pixel i covers input [i k, (i + 1) k), k = n_in / n_out; weight = overlap / k."""
    edges_out = np.arange(n_out + 1) * (n_in / n_out)
    lo = np.maximum(edges_out[:-1, None], np.arange(n_in)[None, :])
    hi = np.minimum(edges_out[1:, None], np.arange(1, n_in + 1)[None, :])
    return np.maximum(hi - lo, 0.0) * (n_out / n_in)


def box_downsample(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(H, W, C) -> (h, w, C) with h <= H, w <= W: each output pixel the mean of the input over its area
    (fractional input pixels weighted by their overlap), so a render at k times the size, reduced, is a
    box-filtered supersampling with k² samples per pixel for any k >= 1."""
    w, h = size
    rows, cols = image.shape[:2]
    if h > rows or w > cols:
        raise PrefilterError(f"box_downsample reduces only: {cols}x{rows} -> {w}x{h}")
    a_y, a_x = _box_weights(rows, h), _box_weights(cols, w)
    rows_reduced = np.tensordot(a_y, np.asarray(image, np.float64), axes=(1, 0))  # (h, W, C)
    return np.tensordot(rows_reduced, a_x, axes=(1, 1)).transpose(0, 2, 1).astype(np.float32)


def false_colour(values: np.ndarray, vmax: float = 1.0) -> np.ndarray:
    """Map scalars (H, W) to linear RGB (H, W, 3) with matplotlib's "magma", values clipped to [0, vmax].

    Magma is the colour map of the FLIP paper's error maps. Its entries are sRGB-encoded; they are decoded
    here so that `write_image` re-encodes them exactly. NaN maps to 0.
    """
    import matplotlib

    if not vmax > 0:
        raise ValueError(f"vmax must be positive, got {vmax}")
    v = np.nan_to_num(np.asarray(values, dtype=np.float64), nan=0.0)
    if v.ndim == 3 and v.shape[2] == 1:
        v = v[:, :, 0]
    if v.ndim != 2:
        raise ValueError(f"expected (H, W) values, got shape {v.shape}")
    srgb = matplotlib.colormaps["magma"](np.clip(v / vmax, 0.0, 1.0))[:, :, :3]
    return srgb_to_linear(srgb).astype(np.float32)


def _label_font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: fixed-size bitmap font only
        return ImageFont.load_default()


def _fit_text(draw, text: str, font, width: int) -> str:
    if draw.textlength(text, font=font) <= width:
        return text
    while text and draw.textlength(text + "...", font=font) > width:
        text = text[:-1]
    return text + "..." if text else ""


def labelled_strip(panels: list[tuple[str, np.ndarray]], label_height: int = 22, gap: int = 2) -> np.ndarray:
    """Panels (label, linear (H, W, 3)) side by side, each under a label bar, `gap` px apart.

    Labels are white text on dark grey in Pillow's default font, truncated with "..." when too wide.
    Panel pixels are copied unchanged; the result is linear float32 (H + label_height, n W + (n-1) gap, 3).
    """
    from PIL import Image, ImageDraw

    if not panels:
        raise ValueError("labelled_strip needs at least one panel")
    images = [np.asarray(img, dtype=np.float32) for _, img in panels]
    shape = images[0].shape
    if len(shape) != 3 or shape[2] != 3:
        raise ValueError(f"panels must be (H, W, 3), got {shape}")
    for (label, _), img in zip(panels, images, strict=True):
        if img.shape != shape:
            raise ValueError(f"panel {label!r} has shape {img.shape}, expected {shape}")
    h, w, _ = shape
    n = len(panels)
    total_w = n * w + (n - 1) * gap
    bar = Image.new("L", (total_w, label_height), LABEL_BACKGROUND)
    draw = ImageDraw.Draw(bar)
    font = _label_font(max(8, round(label_height * 0.62)))
    for i, (label, _) in enumerate(panels):
        text = _fit_text(draw, str(label), font, w - 6)
        if not text:
            continue
        x0 = i * (w + gap)
        left, top, right, bottom = draw.textbbox((0, 0), text, font=font)
        x = x0 + (w - (right - left)) // 2 - left
        y = (label_height - (bottom - top)) // 2 - top
        draw.text((x, y), text, fill=LABEL_FOREGROUND, font=font)
    bar_linear = srgb_to_linear(np.asarray(bar, dtype=np.float64) / 255.0).astype(np.float32)
    out = np.empty((label_height + h, total_w, 3), dtype=np.float32)
    out[:label_height] = bar_linear[:, :, None]
    out[label_height:] = np.float32(srgb_to_linear(LABEL_BACKGROUND / 255.0))
    for i, img in enumerate(images):
        x0 = i * (w + gap)
        out[label_height:, x0 : x0 + w] = img
    return out
