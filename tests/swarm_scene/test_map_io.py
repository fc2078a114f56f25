"""swarm_scene.map_io: nav2 map_server's format, every mode, and its failures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from swarm_common.errors import InputError
from swarm_scene.map_io import load_map, save_map
from swarm_scene.occupancy import OCCUPIED, UNKNOWN, OccupancyMap

DATA = Path(__file__).resolve().parents[1] / "data"


def _yaml(path: Path, image: str, mode: str | None = "trinary", negate=0, occ=0.65, free=0.25,
          resolution=0.1, origin="[-1.0, 2.0, 0.5]", extra: str = "") -> Path:
    lines = [f"image: {image}", f"resolution: {resolution}", f"origin: {origin}",
             f"negate: {negate}", f"occupied_thresh: {occ}", f"free_thresh: {free}"]
    if mode is not None:
        lines.append(f"mode: {mode}")
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


def _sample_map() -> OccupancyMap:
    rng = np.random.default_rng(7)
    data = rng.choice(np.array([UNKNOWN, 0, OCCUPIED], dtype=np.int8), size=(23, 37))
    data[0, 0], data[-1, -1] = OCCUPIED, UNKNOWN  # mark the corners to catch flips
    return OccupancyMap(data=data, resolution=0.05, origin=np.array([-3.25, 1.5, 0.0]))


# ------------------------------------------------------------------------ round trips


@pytest.mark.parametrize(("mode", "suffix"), [("trinary", ".pgm"), ("scale", ".png"),
                                              ("raw", ".pgm")])
def test_save_then_load_round_trip_in_every_mode(tmp_path, mode, suffix):
    occ = _sample_map()
    yaml_path, image_path = save_map(occ, tmp_path / "m", mode=mode)
    assert yaml_path == tmp_path / "m.yaml"
    assert image_path == tmp_path / f"m{suffix}"
    back = load_map(yaml_path)
    np.testing.assert_array_equal(back.data, occ.data)
    assert back.resolution == pytest.approx(0.05)
    assert back.origin == pytest.approx([-3.25, 1.5, 0.0])
    assert back.data.dtype == np.int8


def test_trinary_save_writes_map_saver_pixels_and_yaml(tmp_path):
    occ = _sample_map()
    yaml_path, image_path = save_map(occ, tmp_path / "m")
    with Image.open(image_path) as img:
        assert img.format == "PPM" and img.mode == "L"
        pixels = np.asarray(img)
    flipped = np.flipud(occ.data)  # image row 0 is the map's top row
    assert (pixels[flipped == 0] == 254).all()
    assert (pixels[flipped == OCCUPIED] == 0).all()
    assert (pixels[flipped == UNKNOWN] == 205).all()
    assert yaml_path.read_text() == (
        "image: m.pgm\nmode: trinary\nresolution: 0.05\norigin: [-3.25, 1.5, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def test_saved_scale_values_between_thresholds(tmp_path):
    data = np.array([[0, 10, 19, 20, 30, 42, 50, 64, 65, 90, 100, -1]], dtype=np.int8)
    save_map(OccupancyMap(data, 0.1, np.zeros(3)), tmp_path / "s", mode="scale")
    back = load_map(tmp_path / "s.yaml").data[0]
    # grey = rint((100 - v) / 100 * 255); occ = 1 - grey / 255; between 0.196 and 0.65:
    # rint((occ - 0.196) / (0.65 - 0.196) * 100)
    grey = np.rint((100.0 - data[0, :-1]) / 100.0 * 255.0)
    occ = 1.0 - grey / 255.0
    expected = np.where(occ > 0.65, 100,
                        np.where(occ < 0.196, 0, np.rint((occ - 0.196) / 0.454 * 100)))
    np.testing.assert_array_equal(back[:-1], expected.astype(int))
    assert back[-1] == UNKNOWN
    assert back.tolist()[:5] == [0, 0, 0, 1, 23]


# ------------------------------------------------------------------ map_server's rules


@pytest.mark.parametrize("suffix", [".pgm", ".png"])
def test_trinary_thresholds_over_all_grey_levels(tmp_path, suffix):
    Image.fromarray(np.arange(256, dtype=np.uint8)[None, :]).save(tmp_path / f"g{suffix}")
    values = load_map(_yaml(tmp_path / "g.yaml", f"g{suffix}")).data[0]
    # occ = 1 - v / 255: > 0.65 for v <= 89 (occupied), < 0.25 for v >= 192 (free)
    assert (values[:90] == OCCUPIED).all()
    assert (values[90:192] == UNKNOWN).all()
    assert (values[192:] == 0).all()


def test_negate_swaps_black_and_white(tmp_path):
    Image.fromarray(np.arange(256, dtype=np.uint8)[None, :]).save(tmp_path / "g.pgm")
    values = load_map(_yaml(tmp_path / "g.yaml", "g.pgm", negate=1)).data[0]
    # occ = v / 255: > 0.65 for v >= 166, < 0.25 for v <= 63
    assert (values[:64] == 0).all()
    assert (values[64:166] == UNKNOWN).all()
    assert (values[166:] == OCCUPIED).all()
    assert (load_map(_yaml(tmp_path / "t.yaml", "g.pgm", negate="true")).data == values).all()


def test_scale_mode_interpolates_between_thresholds(tmp_path):
    Image.fromarray(np.array([[0, 89, 90, 128, 191, 192, 255]], dtype=np.uint8)).save(
        tmp_path / "g.pgm")
    values = load_map(_yaml(tmp_path / "g.yaml", "g.pgm", mode="scale")).data[0]
    # v = 128: occ = 127 / 255 = 0.498; (0.498 - 0.25) / 0.4 * 100 = 62.0 → 62
    # v = 90: occ = 0.647 → 99.3 → 99; v = 191: occ = 0.251 → 0.25 → 0
    assert values.tolist() == [100, 100, 99, 62, 0, 0, 0]


def test_raw_mode_takes_values_as_they_are(tmp_path):
    Image.fromarray(np.arange(256, dtype=np.uint8)[None, :]).save(tmp_path / "g.pgm")
    values = load_map(_yaml(tmp_path / "g.yaml", "g.pgm", mode="raw", negate=1)).data[0]
    assert values[:101].tolist() == list(range(101))  # negate does not apply in raw mode
    assert (values[101:] == UNKNOWN).all()


def test_rgb_channels_are_averaged(tmp_path):
    rgb = np.array([[[255, 0, 0], [0, 255, 255], [255, 255, 255], [60, 60, 60]]],
                   dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "c.png")
    values = load_map(_yaml(tmp_path / "c.yaml", "c.png")).data[0]
    # shades 1/3 (occ 0.667 → occupied), 2/3 (occ 0.333 → unknown), 1 (free), 60/255 (occ)
    assert values.tolist() == [OCCUPIED, UNKNOWN, 0, OCCUPIED]


def test_alpha_is_averaged_in_trinary_and_means_unknown_in_scale(tmp_path):
    rgba = np.array([[[255, 255, 255, 255], [255, 255, 255, 0], [0, 0, 0, 0],
                      [255, 255, 255, 254]]], dtype=np.uint8)
    Image.fromarray(rgba).save(tmp_path / "a.png")
    trinary = load_map(_yaml(tmp_path / "t.yaml", "a.png")).data[0]
    # trinary: shade = (r + g + b + a) / 4: 1.0 → free; 0.75 → occ 0.25, not < 0.25 → unknown;
    # 0 → occupied; (3 * 255 + 254) / 4 / 255 = 0.999 → free
    assert trinary.tolist() == [0, UNKNOWN, OCCUPIED, 0]
    scale = load_map(_yaml(tmp_path / "s.yaml", "a.png", mode="scale")).data[0]
    assert scale.tolist() == [0, UNKNOWN, UNKNOWN, UNKNOWN]  # only fully opaque pixels count


def test_grey_alpha_and_16_bit_images(tmp_path):
    la = np.array([[[0, 255], [255, 255], [255, 0]]], dtype=np.uint8)
    Image.fromarray(la).save(tmp_path / "la.png")  # (H, W, 2) → grey + alpha
    assert load_map(_yaml(tmp_path / "la.yaml", "la.png")).data[0].tolist() == [
        OCCUPIED, 0, UNKNOWN]  # (3 * 255 + 0) / 4 = 0.75 → occ 0.25 → unknown
    deep = np.array([[0, 30000, 65535]], dtype=np.uint16)
    Image.fromarray(deep).save(tmp_path / "d.png")
    # occ = 1 - v / 65535: 1.0, 0.542, 0.0
    assert load_map(_yaml(tmp_path / "d.yaml", "d.png")).data[0].tolist() == [
        OCCUPIED, UNKNOWN, 0]


def test_rows_are_flipped_and_origin_kept(tmp_path):
    img = np.full((3, 2), 254, dtype=np.uint8)
    img[0, 0] = 0  # top-left pixel occupied
    Image.fromarray(img).save(tmp_path / "f.pgm")
    occ = load_map(_yaml(tmp_path / "f.yaml", "f.pgm"))
    assert occ.data.shape == (3, 2)
    assert occ.data[2, 0] == OCCUPIED and occ.data.sum() == OCCUPIED  # row 0 is the bottom
    assert occ.origin.tolist() == [-1.0, 2.0, 0.5]
    assert occ.resolution == 0.1
    assert occ.cell_to_world([2, 0]) == pytest.approx([-0.95, 2.25])


def test_image_path_relative_to_the_yaml_or_absolute(tmp_path, monkeypatch):
    (tmp_path / "img").mkdir()
    (tmp_path / "meta").mkdir()
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "img" / "r.pgm")
    monkeypatch.chdir(tmp_path / "img")  # the current directory must not matter
    relative = load_map(_yaml(tmp_path / "meta" / "r.yaml", "../img/r.pgm"))
    absolute = load_map(_yaml(tmp_path / "meta" / "a.yaml", str(tmp_path / "img" / "r.pgm")))
    assert (relative.data == OCCUPIED).all() and (absolute.data == OCCUPIED).all()


def test_mode_defaults_to_trinary_and_unknown_keys_are_ignored(tmp_path):
    Image.fromarray(np.array([[0, 205, 254]], dtype=np.uint8)).save(tmp_path / "g.pgm")
    occ = load_map(_yaml(tmp_path / "g.yaml", "g.pgm", mode=None, free=0.196,
                         extra="elevation_image: e.pgm\n"))
    assert occ.data[0].tolist() == [OCCUPIED, UNKNOWN, 0]


def test_ascii_pgm_fixture(tmp_path):
    occ = load_map(DATA / "map_ascii.yaml")
    # map_ascii.pgm (P2, 4 x 3): top row 0 0 0 0, middle 254 205 205 0, bottom 254 254 254 0
    assert occ.data.tolist() == [[0, 0, 0, OCCUPIED], [0, UNKNOWN, UNKNOWN, OCCUPIED],
                                 [OCCUPIED] * 4]
    assert occ.resolution == 0.5 and occ.origin.tolist() == [-1.0, -0.5, 0.0]


# ------------------------------------------------------------------------ bad input


def _assert_one_line(err, starts: str, *parts: str) -> None:
    msg = str(err.value)
    assert msg.startswith(starts), msg
    for part in parts:
        assert part in msg, msg
    assert "\n" not in msg


def test_missing_yaml(tmp_path):
    with pytest.raises(InputError) as err:
        load_map(tmp_path / "nope.yaml")
    _assert_one_line(err, str(tmp_path / "nope.yaml"), "no such map file")


@pytest.mark.parametrize("key", ["image", "resolution", "origin", "negate", "occupied_thresh",
                                 "free_thresh"])
def test_missing_key(tmp_path, key):
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "g.pgm")
    path = _yaml(tmp_path / "g.yaml", "g.pgm")
    path.write_text("".join(line + "\n" for line in path.read_text().splitlines()
                            if not line.startswith(f"{key}:")))
    with pytest.raises(InputError) as err:
        load_map(path)
    _assert_one_line(err, str(path), f"missing key '{key}'")


def test_misspelt_key_is_pointed_at(tmp_path):
    path = tmp_path / "g.yaml"
    path.write_text("image: g.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                    "occupied_threshold: 0.65\nfree_thresh: 0.25\n")
    with pytest.raises(InputError) as err:
        load_map(path)
    _assert_one_line(err, str(path), "missing key 'occupied_thresh' (found 'occupied_threshold'?)")


@pytest.mark.parametrize(("field", "value", "problem"), [
    ("free", 0.7, "0 <= free_thresh < occupied_thresh <= 1"),
    ("occ", 1.5, "0 <= free_thresh < occupied_thresh <= 1"),
    ("free", -0.1, "0 <= free_thresh < occupied_thresh <= 1"),
    ("occ", "abc", "'occupied_thresh' must be a number"),
    ("mode", "trinery", "'mode' must be one of trinary, scale, raw, got 'trinery' (did you mean"),
    ("resolution", 0, "'resolution' must be positive"),
    ("resolution", "[1, 2]", "'resolution' must be a number"),
    ("origin", "[0, 0]", "'origin' must be [x, y, yaw]"),
    ("origin", "[0, x, 0]", "'origin' must be a number"),
    ("negate", "[1]", "'negate' must be 0 or 1"),
])
def test_bad_values(tmp_path, field, value, problem):
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "g.pgm")
    path = _yaml(tmp_path / "g.yaml", "g.pgm", **{field: value})
    with pytest.raises(InputError) as err:
        load_map(path)
    _assert_one_line(err, str(path), problem)


@pytest.mark.parametrize(("content", "problem"), [
    ("image: [unclosed\n", "invalid YAML at line"),
    ("- just\n- a list\n", "not a map_server YAML"),
    ("", "not a map_server YAML"),
])
def test_unparsable_yaml(tmp_path, content, problem):
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    with pytest.raises(InputError) as err:
        load_map(path)
    _assert_one_line(err, str(path), problem)


def test_missing_image(tmp_path):
    path = _yaml(tmp_path / "g.yaml", "gone.pgm")
    with pytest.raises(InputError) as err:
        load_map(path)
    _assert_one_line(err, str(path), "image 'gone.pgm' not found", str(tmp_path / "gone.pgm"))


@pytest.mark.parametrize(("name", "make", "problem"), [
    ("t.pgm", lambda p: p.write_bytes(b"P5\n10 10\n255\n" + bytes(37)), "corrupt or truncated"),
    ("t.png", lambda p: (Image.fromarray(np.zeros((50, 50), dtype=np.uint8)).save(p),
                         p.write_bytes(p.read_bytes()[:60])), "corrupt or truncated"),
    ("g.pgm", lambda p: p.write_bytes(b"this is not an image"), "not a PGM/PNG image"),
])
def test_truncated_or_corrupt_image(tmp_path, name, make, problem):
    make(tmp_path / name)
    path = _yaml(tmp_path / "g.yaml", name)
    with pytest.raises(InputError) as err:
        load_map(path)
    _assert_one_line(err, str(path), problem)


def test_save_into_missing_directory(tmp_path):
    with pytest.raises(InputError) as err:
        save_map(_sample_map(), tmp_path / "no" / "m")
    _assert_one_line(err, str(tmp_path / "no" / "m"), "does not exist")
