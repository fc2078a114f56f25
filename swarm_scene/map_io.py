"""nav2 map_server maps: a YAML file and a PGM/PNG image, read and written as map_server does.

The YAML keys are map_server's: ``image`` (a path, relative to the YAML file unless absolute),
``resolution`` [m/cell], ``origin`` [x, y, yaw] of the lower-left pixel [m, m, rad], ``negate``
(0/1), ``occupied_thresh``, ``free_thresh`` (0..1) and ``mode`` (``trinary`` by default,
``scale``, ``raw``); other keys are ignored, as map_server ignores them.

Pixel conversion (nav2_map_server ``map_io.cpp``, ``loadMapFromFile``): ``shade`` is the mean of
the R, G, B channels scaled to 0..1 (a grey image has one value; in trinary mode the alpha channel
of an image that has one is averaged in as a fourth channel); ``occ = 1 - shade`` (``shade`` if
``negate``). Trinary: ``occ > occupied_thresh`` → 100, ``occ < free_thresh`` → 0, else -1.
Scale: a pixel that is not fully opaque → -1, then as trinary but in between thresholds
``rint((occ - free) / (occupied - free) * 100)``. Raw: ``round(shade * 255)`` if it is 0..100,
else -1 (``negate`` does not apply).

Writing follows map_saver (``tryWriteMapToFile``): trinary PGM with 254 free, 0 occupied, 205
unknown; scale PNG grey ``(100 - value) / 100`` with transparent unknown; raw PGM with the value
itself and 255 unknown. The YAML gets ``free_thresh: 0.196`` (ROS 1 map_saver's value) rather than
nav2's 0.25 default, because 205 ("unknown") would load as free under 0.25 (1 - 205/255 = 0.196;
see slam_toolbox issue #587).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml
from PIL import Image, UnidentifiedImageError

from swarm_common.errors import InputError, did_you_mean
from swarm_scene.occupancy import OCCUPIED, UNKNOWN, OccupancyMap

MODES = ("trinary", "scale", "raw")
REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196


# ---------------------------------------------------------------------------------------- load


def _number(doc: dict, key: str, where: str) -> float:
    value = doc[key]
    if isinstance(value, bool):
        raise InputError(f"{where}: '{key}' must be a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: '{key}' must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise InputError(f"{where}: '{key}' must be finite, got {value!r}")
    return number


def _read_yaml(path: Path) -> dict:
    where = str(path)
    if not path.is_file():
        raise InputError(f"{where}: no such map file" if not path.exists()
                         else f"{where}: not a file")
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"{where}: invalid YAML{at}: {problem}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{where}: cannot read: {exc}") from None
    if not isinstance(doc, dict):
        raise InputError(f"{where}: not a map_server YAML (expected a mapping with keys "
                         f"{', '.join(REQUIRED_KEYS)})")
    for key in REQUIRED_KEYS:
        if key not in doc:
            others = [k for k in doc if isinstance(k, str) and k not in REQUIRED_KEYS]
            hint = did_you_mean(key, others).replace("did you mean", "found")
            raise InputError(f"{where}: missing key '{key}'{hint}")
    return doc


def _parse_meta(doc: dict, where: str) -> dict:
    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise InputError(f"{where}: 'image' must be a file name, got {image!r}")
    resolution = _number(doc, "resolution", where)
    if resolution <= 0.0:
        raise InputError(f"{where}: 'resolution' must be positive [m/cell], got {resolution:g}")
    origin = doc["origin"]
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise InputError(f"{where}: 'origin' must be [x, y, yaw], got {origin!r}")
    origin = np.array([_number({"origin": v}, "origin", where) for v in origin])
    occ_th = _number(doc, "occupied_thresh", where)
    free_th = _number(doc, "free_thresh", where)
    if not 0.0 <= free_th < occ_th <= 1.0:
        raise InputError(f"{where}: thresholds must satisfy 0 <= free_thresh < occupied_thresh "
                         f"<= 1, got free_thresh {free_th:g}, occupied_thresh {occ_th:g}")
    negate = doc["negate"]
    if isinstance(negate, str) and negate.strip().lower() in ("true", "false", "0", "1"):
        negate = negate.strip().lower() in ("true", "1")
    if not isinstance(negate, bool | int):
        raise InputError(f"{where}: 'negate' must be 0 or 1, got {negate!r}")
    mode = doc.get("mode", "trinary")
    if mode not in MODES:
        raise InputError(f"{where}: 'mode' must be one of {', '.join(MODES)}, got {mode!r}"
                         f"{did_you_mean(str(mode), MODES)}")
    return {"image": image.strip(), "resolution": resolution, "origin": origin,
            "occupied_thresh": occ_th, "free_thresh": free_th, "negate": bool(negate),
            "mode": mode}


def _read_pixels(path: Path, where: str) -> tuple[np.ndarray, np.ndarray | None, float]:
    """Channels (H, W, C) float, alpha (H, W) or None, and the full-scale value of the image."""
    try:
        with Image.open(path) as img:
            img.load()
            mode = img.mode
            if mode == "P" or mode == "PA":
                img = img.convert("RGBA" if ("transparency" in img.info or mode == "PA")
                                  else "RGB")
            elif mode == "1":
                img = img.convert("L")
            elif mode in ("CMYK", "YCbCr", "LAB", "HSV", "RGBX"):
                img = img.convert("RGB")
            elif mode == "La":
                img = img.convert("LA")
            elif mode == "RGBa":
                img = img.convert("RGBA")
            arr = np.asarray(img)
            mode = img.mode
    except FileNotFoundError:
        raise InputError(f"{where}: image '{path}' not found") from None
    except UnidentifiedImageError:
        raise InputError(f"{where}: image '{path.name}' is not a PGM/PNG image Pillow can read")\
            from None
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as exc:
        raise InputError(f"{where}: image '{path.name}' is corrupt or truncated: {exc}")\
            from None
    if mode in ("L", "RGB"):
        return arr.reshape(arr.shape[0], arr.shape[1], -1).astype(float), None, 255.0
    if mode in ("LA", "RGBA"):
        return arr[..., :-1].astype(float), arr[..., -1].astype(float), 255.0
    if mode.startswith("I;16") or mode == "I":
        return arr.astype(float)[..., None], None, 65535.0  # 16-bit grey
    raise InputError(f"{where}: image '{path.name}' has pixel mode {mode}, which map_server "
                     "does not read (use 8-bit grey, RGB or RGBA)")


def pixels_to_occupancy(channels: np.ndarray, alpha: np.ndarray | None, full_scale: float,
                        mode: str, negate: bool, occupied_thresh: float,
                        free_thresh: float) -> np.ndarray:
    """Convert image pixels to occupancy values by map_server's rules (see the module doc).

    Args:
        channels: (H, W, C) colour values, C = 1 (grey) or 3 (R, G, B), in 0..full_scale.
        alpha: (H, W) alpha (full_scale = opaque) or None for an image without alpha.
        full_scale: the value of white / opaque (255 for 8-bit images).
        mode: "trinary", "scale" or "raw".
        negate: whether black is free.
        occupied_thresh: occupancy above which a cell is occupied (0..1).
        free_thresh: occupancy below which a cell is free (0..1).

    Returns:
        (H, W) int8 values in image layout (row 0 at the top): -1, 0..100.
    """
    grey = channels.shape[2] == 1
    # GraphicsMagick gives R = G = B for grey images: map_server averages three equal channels.
    parts = [channels[..., 0]] * 3 if grey else [channels[..., i] for i in range(3)]
    if mode == "trinary" and alpha is not None:
        parts.append(alpha)
    shade = (sum(parts) / len(parts)) / full_scale
    occ = shade if negate else 1.0 - shade
    out = np.full(shade.shape, UNKNOWN, dtype=np.int8)
    if mode == "raw":
        value = np.floor(shade * 255.0 + 0.5)  # std::round, half away from zero
        ok = (value >= 0) & (value <= OCCUPIED)
        out[ok] = value[ok].astype(np.int8)
        return out
    occupied = occupied_thresh < occ
    free = occ < free_thresh
    out[occupied] = OCCUPIED
    out[free & ~occupied] = 0
    if mode == "scale":
        between = ~occupied & ~free
        scaled = np.rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100.0)
        out[between] = scaled[between].astype(np.int8)
        if alpha is not None:
            out[alpha != full_scale] = UNKNOWN
    return out


def load_map(yaml_path: str | Path) -> OccupancyMap:
    """Load a nav2 map_server map (YAML + PGM/PNG), whole format.

    Args:
        yaml_path: the map's YAML file.

    Returns:
        The :class:`OccupancyMap` (rows flipped so that row 0 is at ``origin`` y), values -1,
        0..100, resolution [m/cell] and origin (3,) [m, m, rad] from the YAML.

    Raises:
        InputError: missing or invalid YAML, a missing key or bad value (thresholds out of
            0 <= free < occupied <= 1, unknown mode, non-positive resolution, origin not 3
            numbers), a missing, unreadable, corrupt or truncated image.

    Source: nav2_map_server ``map_io.cpp`` (``loadMapYaml``, ``loadMapFromFile``).
    """
    path = Path(yaml_path)
    where = str(yaml_path)
    meta = _parse_meta(_read_yaml(path), where)
    image_path = Path(meta["image"]).expanduser()
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    if not image_path.is_file():
        raise InputError(f"{where}: image '{meta['image']}' not found (looked for {image_path})")
    channels, alpha, full_scale = _read_pixels(image_path, where)
    if channels.shape[0] == 0 or channels.shape[1] == 0:
        raise InputError(f"{where}: image '{meta['image']}' is empty")
    cells = pixels_to_occupancy(channels, alpha, full_scale, meta["mode"], meta["negate"],
                                meta["occupied_thresh"], meta["free_thresh"])
    return OccupancyMap(data=np.ascontiguousarray(np.flipud(cells)),
                        resolution=meta["resolution"], origin=meta["origin"])


# ---------------------------------------------------------------------------------------- save


def _fmt(value: float) -> str:
    value = round(float(value), 9)
    return repr(0.0 if value == 0.0 else value)


def save_map(occ: OccupancyMap, prefix: str | Path, mode: str = "trinary") -> tuple[Path, Path]:
    """Write a map as map_saver does: ``PREFIX.yaml`` and ``PREFIX.pgm`` (``.png`` in scale mode).

    Args:
        occ: the map (-1 unknown, 0..100).
        prefix: path without suffix; the YAML names the image by its file name only.
        mode: "trinary" (default; PGM 254 free / 0 occupied / 205 unknown with thresholds
            0.196 and 0.65), "scale" (RGBA PNG, grey (100 - value) / 100, unknown transparent)
            or "raw" (PGM, the value itself, 255 unknown).

    Returns:
        (yaml_path, image_path).

    Raises:
        InputError: an unknown mode, or a directory that does not exist or cannot be written.

    Source: nav2_map_server ``map_io.cpp`` (``tryWriteMapToFile``).
    """
    if mode not in MODES:
        raise InputError(f"map mode must be one of {', '.join(MODES)}, got {mode!r}")
    prefix = Path(prefix)
    image_path = prefix.parent / f"{prefix.name}.{'png' if mode == 'scale' else 'pgm'}"
    yaml_path = prefix.parent / f"{prefix.name}.yaml"
    if not prefix.parent.is_dir():
        raise InputError(f"{prefix}: directory '{prefix.parent}' does not exist")
    data = np.flipud(np.asarray(occ.data)).astype(np.int16)  # image layout: row 0 at the top
    known = (data >= 0) & (data <= 100)
    if mode == "trinary":
        free_int = round(SAVE_FREE_THRESH * 100.0)
        occ_int = round(SAVE_OCCUPIED_THRESH * 100.0)
        pixels = np.full(data.shape, 205, dtype=np.uint8)
        pixels[known & (data <= free_int)] = 254
        pixels[known & (data >= occ_int)] = 0
        image = Image.fromarray(pixels)
    elif mode == "raw":
        pixels = np.where(known, data, 255).astype(np.uint8)
        image = Image.fromarray(pixels)
    else:
        grey = np.where(known, np.rint((100.0 - data) / 100.0 * 255.0), 128).astype(np.uint8)
        rgba = np.dstack((grey, grey, grey, np.where(known, 255, 0).astype(np.uint8)))
        image = Image.fromarray(rgba)
    x, y, yaw = (float(v) for v in occ.origin)
    text = (
        f"image: {image_path.name}\n"
        f"mode: {mode}\n"
        f"resolution: {_fmt(occ.resolution)}\n"
        f"origin: [{_fmt(x)}, {_fmt(y)}, {_fmt(yaw)}]\n"
        f"negate: 0\n"
        f"occupied_thresh: {SAVE_OCCUPIED_THRESH}\n"
        f"free_thresh: {SAVE_FREE_THRESH}\n"
    )
    try:
        image.save(image_path)
        yaml_path.write_text(text)
    except OSError as exc:
        raise InputError(f"{prefix}: cannot write the map: {exc.strerror or exc}") from None
    return yaml_path, image_path
