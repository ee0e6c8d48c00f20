"""8-bit grey rasters for ROS maps: our own PGM (P2, P5) reader and writer, pillow for the rest.

PGM (Netpbm, https://netpbm.sourceforge.net/doc/pgm.html): magic ``P5`` (binary) or
``P2`` (plain text), whitespace-separated width, height and maxval, ``#`` comments to the
end of a line in the header, then width x height samples, rows top to bottom. Samples
are scaled to 0..255 when maxval < 255; maxval > 255 (16-bit) is refused, as ROS
map_server reads 8-bit images.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrfswarm.errors import ScenarioError
from mrfswarm.file_input import read_bytes
from mrfswarm.maps.grid import MAX_CELLS

_TOKEN = re.compile(rb"\s*(?:#[^\n]*\n\s*)*([^\s#]+)")
_SIXTEEN_BIT = "16-bit and wider images are not supported (ROS map_server reads 8-bit images); convert it to 8-bit grey"


@dataclass(frozen=True)
class Raster:
    """An image as ROS map_server sees it.

    ``grey`` is the mean of the colour channels (float, 0..255, row 0 the top row);
    ``alpha`` the alpha channel (uint8) or None when the image has none.
    """

    grey: np.ndarray
    alpha: np.ndarray | None = None


def _header(data: bytes, path: Path) -> tuple[bytes, list[int], int]:
    """Magic, [width, height, maxval], and the offset just after the header's last token."""
    magic = data[:2]
    pos = 2
    values = []
    for name in ("width", "height", "maxval"):
        m = _TOKEN.match(data, pos)
        if m is None:
            raise ScenarioError(f"{path}: truncated PGM header (no {name})")
        tok = m.group(1)
        if not tok.isdigit():
            raise ScenarioError(f"{path}: PGM {name} {tok[:20].decode('latin-1')!r} is not a positive integer")
        values.append(int(tok))
        pos = m.end()
    return magic, values, pos


def read_pgm(path: Path) -> Raster:
    """Read an 8-bit PGM (P5 binary or P2 plain).

    Raises
    ------
    ScenarioError
        Unreadable file, bad header, 16-bit samples, truncated or out-of-range data.
    """
    data = read_bytes(path, "map image")
    magic, (w, h, maxval), pos = _header(data, path)
    if magic not in (b"P5", b"P2"):
        raise ScenarioError(f"{path}: not a PGM file (magic {magic!r}, expected b'P5' or b'P2')")
    if w < 1 or h < 1:
        raise ScenarioError(f"{path}: PGM size {w} x {h}: width and height must be >= 1")
    if w * h > MAX_CELLS:
        raise ScenarioError(f"{path}: PGM size {w} x {h} exceeds the limit of {MAX_CELLS} cells")
    if not 1 <= maxval <= 65535:
        raise ScenarioError(f"{path}: PGM maxval {maxval} must be in 1..65535")
    if maxval > 255:
        raise ScenarioError(f"{path}: PGM maxval {maxval}: {_SIXTEEN_BIT}")
    n = w * h
    if magic == b"P5":
        # exactly one whitespace byte separates maxval from the raster
        if pos >= len(data) or not data[pos:pos + 1].isspace():
            raise ScenarioError(f"{path}: PGM header not followed by a whitespace byte")
        raw = data[pos + 1:pos + 1 + n]
        if len(raw) < n:
            raise ScenarioError(f"{path}: truncated PGM: expected {n} bytes of pixel data ({w} x {h}), found {len(raw)}")
        samples = np.frombuffer(raw, np.uint8).astype(np.float64)
    else:
        body = re.sub(rb"#[^\n]*", b" ", data[pos:])
        toks = body.split()
        if len(toks) < n:
            raise ScenarioError(f"{path}: truncated PGM: expected {n} samples ({w} x {h}), found {len(toks)}")
        try:
            samples = np.array([int(t) for t in toks[:n]], dtype=np.float64)
        except ValueError:
            bad = next(t for t in toks[:n] if not t.isdigit())
            raise ScenarioError(f"{path}: PGM sample {bad[:20].decode('latin-1')!r} is not an integer") from None
    if samples.max() > maxval:
        raise ScenarioError(f"{path}: PGM sample {int(samples.max())} exceeds maxval {maxval}")
    if maxval != 255:
        samples = np.round(samples * (255.0 / maxval))
    return Raster(samples.reshape(h, w))


def read_raster(path: Path) -> Raster:
    """Read a map image: PGM (P2/P5) with our reader, anything else (PNG, ...) with pillow.

    Colour images become the mean of their colour channels (ROS map_server averages the
    channels); palette and 1-bit images are expanded first.

    Raises
    ------
    ScenarioError
        Missing, unreadable or unsupported (16-bit, float) image; names the file.
    """
    try:
        with open(path, "rb") as f:
            magic = f.read(2)
    except OSError as e:
        raise ScenarioError(f"cannot read map image {str(path)!r}: {e.strerror or e}") from e
    if magic in (b"P5", b"P2"):
        return read_pgm(path)
    from PIL import Image, UnidentifiedImageError  # noqa: PLC0415 (pillow only when a ROS map is read)

    try:
        with Image.open(path) as im:
            im.load()
            mode = im.mode
            if mode.startswith("I") or mode == "F":
                raise ScenarioError(f"{path}: image mode {mode}: {_SIXTEEN_BIT}")
            if mode in ("P", "PA", "La", "RGBa") or "transparency" in im.info:
                arr = np.asarray(im.convert("RGBA"))
                mode = "RGBA"
            elif mode in ("L", "LA", "RGB", "RGBA"):
                arr = np.asarray(im)
            elif mode == "1":
                arr = np.asarray(im.convert("L"))
                mode = "L"
            else:  # CMYK, YCbCr, LAB, HSV: colour without alpha
                arr = np.asarray(im.convert("RGB"))
                mode = "RGB"
    except ScenarioError:
        raise
    except UnidentifiedImageError:
        raise ScenarioError(f"{path}: not an image file pillow can read (PGM, PNG, BMP, ...)") from None
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:  # truncated or corrupt data
        detail = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ScenarioError(f"{path}: unreadable image ({detail})") from None
    if arr.shape[0] * arr.shape[1] > MAX_CELLS:
        raise ScenarioError(f"{path}: image size {arr.shape[1]} x {arr.shape[0]} exceeds the limit of {MAX_CELLS} cells")
    if mode == "L":
        return Raster(arr.astype(np.float64))
    if mode == "LA":
        return Raster(arr[..., 0].astype(np.float64), arr[..., 1].copy())
    if mode == "RGB":
        return Raster(arr.astype(np.float64).mean(axis=-1))
    return Raster(arr[..., :3].astype(np.float64).mean(axis=-1), arr[..., 3].copy())


def write_pgm(path: Path, grey: np.ndarray) -> None:
    """Write an 8-bit binary PGM (P5); ``grey`` is uint8 (rows, columns), row 0 the top row.

    Raises
    ------
    ScenarioError
        The file cannot be written.
    """
    grey = np.ascontiguousarray(grey, dtype=np.uint8)
    h, w = grey.shape
    try:
        path.write_bytes(b"P5\n# CREATOR: mrfswarm\n%d %d\n255\n" % (w, h) + grey.tobytes())
    except OSError as e:
        raise ScenarioError(f"cannot write map image {str(path)!r}: {e.strerror or e}") from e
