"""Data images as float arrays: 8/16-bit PNG and float EXR, read and written without colour conversion.

For maps whose values are data (normals, heights, nanostructures), unlike images.py (colour images with
sRGB encoding and metadata). Arrays are in file order (top row first); errors are one-line
PrefilterErrors naming the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from prefilter import PrefilterError

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (library messages can span several)."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _png16_colour(path: Path, mode: str) -> np.ndarray:
    """A 16-bit RGB/RGBA PNG as uint16. Pillow keeps only the high bytes of such files, so it decodes the
    file twice, unpacking the big-endian samples once as high bytes and once as low bytes."""
    from PIL import Image

    planes = []
    for order in ("16B", "16L"):
        with Image.open(path) as im:
            tiles = list(im.tile)
            if len(tiles) != 1 or tiles[0][3] != f"{mode};16B":
                raise PrefilterError(f"{path}: cannot decode this 16-bit {mode} PNG layout; save it as EXR")
            tile = tiles[0]
            rawmode = f"{mode};{order}"
            im.tile = [tile._replace(args=rawmode) if hasattr(tile, "_replace") else (*tile[:3], rawmode)]
            planes.append(np.asarray(im).astype(np.uint16))
    return (planes[0] << 8) | planes[1]


def read_png(path: Path) -> tuple[np.ndarray, float]:
    """(H, W, C) float64 in [0, 1] in file order (top row first), and the size of one code value."""
    import imageio.v3 as iio

    with open(path, "rb") as f:
        head = f.read(33)
    if len(head) < 33 or head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise PrefilterError(f"{path}: not a PNG file")
    depth, colour_type = head[24], head[25]
    try:
        if depth == 16 and colour_type in (2, 6):
            raw = _png16_colour(path, "RGB" if colour_type == 2 else "RGBA")
        else:
            raw = iio.imread(path, plugin="pillow")
    except PrefilterError:
        raise
    except Exception as exc:  # Pillow/imageio raise many kinds
        raise PrefilterError(f"{path}: cannot read PNG ({one_line(exc)})") from None
    raw = np.asarray(raw)
    if raw.ndim == 2:
        raw = raw[:, :, None]
    if colour_type == 4 and raw.shape[2] == 4:  # Pillow widens 16-bit grey+alpha to RGBA
        raw = raw[:, :, [0, 3]]
    top = 1 if raw.dtype == bool else np.iinfo(raw.dtype).max
    return raw.astype(np.float64) / top, 1.0 / top


def read_exr(path: Path) -> tuple[np.ndarray, list[str]]:
    """(H, W, C) float64 in file order and the channel names, RGB(A) first when present."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path)) as exr:
            channels = {name: np.asarray(ch.pixels, dtype=np.float64) for name, ch in exr.channels().items()}
    except Exception as exc:
        raise PrefilterError(f"{path}: cannot read EXR ({one_line(exc)})") from None
    planes: list[np.ndarray] = []
    names: list[str] = []
    for combined in ("RGBA", "RGB"):
        if combined in channels:
            data = channels.pop(combined)
            planes += [data[:, :, c] for c in range(data.shape[2])]
            names += list(combined)
            break
    else:
        for name in ("R", "G", "B", "A", "Y"):
            if name in channels:
                planes.append(channels.pop(name))
                names.append(name)
    for name in sorted(channels):
        data = channels[name]
        if data.ndim == 2:
            planes.append(data)
            names.append(name)
    if not planes:
        raise PrefilterError(f"{path}: EXR has no image channels")
    return np.stack(planes, axis=2), names


def write_exr(path: Path, name: str, pixels: np.ndarray) -> None:
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {name: np.ascontiguousarray(pixels, dtype=np.float32)}).write(str(path))
