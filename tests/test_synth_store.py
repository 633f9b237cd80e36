"""A short sequence end to end into the Zarr store and back, noise determinism, the entry
point, the lab-style export."""

import dataclasses
from importlib.metadata import entry_points

import numpy as np
import pytest

import rollfric.io.readers
import sim
import synth
from synth.camera import CameraModel
from synth.pipeline import truth_table
from synth.sensor import NOISES, Sensor

CAM = CameraModel(width=160, height=128, center_px=(80.0, -500.0))


@pytest.fixture(scope="module")
def traj():
    # released near the bottom so the ball stays inside the small crop
    return sim.simulate(sim.Scenario(theta0=0.03, duration=0.011))


@pytest.fixture(scope="module")
def rec_path(traj, tmp_path_factory):
    out = tmp_path_factory.mktemp("synth") / "rec.zarr"
    synth.render(traj, out, scene=synth.SceneConfig(camera=CAM),
                 sensor=synth.noise_preset("realistic"), seed=7, workers=1)
    return out


def test_store_round_trip(traj, rec_path):
    rec = synth.open_recording(rec_path)
    n = len(traj)
    assert len(rec) == n and rec.frames.shape == (n, 128, 160)
    assert rec.frames.dtype == np.uint8 and rec.frames[0].dtype == np.uint8
    assert rec.frames.fps == 1000.0
    expected = truth_table(traj, CAM, 0.005)
    for name, values in expected.items():
        np.testing.assert_array_equal(rec.truth[name].to_numpy(), values)
    assert rec.attrs["setup"]["cylinder"]["center_px"] == [80.0, -500.0]
    assert rec.attrs["seed"] == 7 and rec.attrs["sensor"]["read_noise"] == 8.0
    assert "pyrender-maintained" in rec.attrs["versions"] or "pyrender2" in rec.attrs["versions"]
    # the ball is where the truth says: the darkest blob's centroid near (x_px, y_px)
    clean = rec.frames.clean(5)
    dark = np.clip(rec.frames.clean_background() - clean, 0, None)
    yy, xx = np.mgrid[0:128, 0:160]
    cx, cy = (dark * xx).sum() / dark.sum(), (dark * yy).sum() / dark.sum()
    assert abs(cx - rec.truth.x_px[5]) < 8 and abs(cy - rec.truth.y_px[5]) < 8


def test_noise_is_deterministic_with_a_seed(rec_path):
    a = synth.open_recording(rec_path).frames
    b = synth.open_recording(rec_path).frames
    for i in (0, 4, len(a) - 1):
        assert a[i].tobytes() == b[i].tobytes()
        assert a[i].tobytes() == a[i].tobytes()
    assert a[1].tobytes() != a[2].tobytes() or not np.array_equal(a.clean(1), a.clean(2))
    s1 = Sensor(synth.noise_preset("realistic"), (128, 160), seed=1)
    s2 = Sensor(synth.noise_preset("realistic"), (128, 160), seed=2)
    counts = a.clean_counts(3)
    scale = int(a.frame_scale)
    assert s1.apply(counts, scale, 3).tobytes() == s1.apply(counts, scale, 3).tobytes()
    assert s1.apply(counts, scale, 3).tobytes() != s2.apply(counts, scale, 3).tobytes()
    assert s1.apply(counts, scale, 3).tobytes() != s1.apply(counts, scale, 4).tobytes()
    # the noise has the rms the model says: shot + read noise on a flat field
    flat = np.full((128, 160), scale // 2, dtype=np.int32)
    cfg = synth.SensorConfig(read_noise=8.0, full_well=10000.0)
    frames = np.stack([Sensor(cfg, flat.shape, 0).apply(flat, scale, i) for i in range(4)])
    e = 0.5 ** 2.2 * 10000.0
    expected_dn = np.sqrt(e + 64.0) * 255 / 10000.0
    measured = frames.astype(float).std(axis=0).mean() * np.sqrt(4 / 3)
    assert measured == pytest.approx(np.sqrt(expected_dn ** 2 + 1 / 12), rel=0.1)


def _rois(h, w, k, seed):
    """Random regions plus the whole frame, the corners and edge strips."""
    r = np.random.default_rng(seed)
    out = [(0, h, 0, w), (0, 1, 0, 1), (h - 1, h, w - 1, w), (0, h, w - 5, w), (h - 3, h, 0, w),
           (60, 70, 60, 70)]
    for _ in range(k):
        y0, x0 = int(r.integers(0, h)), int(r.integers(0, w))
        out.append((y0, int(r.integers(y0 + 1, h + 1)), x0, int(r.integers(x0 + 1, w + 1))))
    return out


@pytest.mark.parametrize("noise", NOISES)
@pytest.mark.parametrize("bit_depth", [8, 12])
def test_sensor_is_block_local(bit_depth, noise):
    # every part of the model on: a crop is the same crop of the full frame, to the byte, for a
    # frame size that is not a multiple of the noise tile, and odd region starts and ends
    from synth.sensor import TILE

    cfg = synth.SensorConfig(bit_depth=bit_depth, read_noise=8.0, black_level=3.0,
                             vignetting=0.2, prnu=0.01, dsnu=5.0)
    h, w = 150, 203
    scale = 1000
    counts = np.random.default_rng(3).integers(0, scale + 1, (h, w)).astype(np.int32)
    s = Sensor(cfg, (h, w), seed=11, noise=noise)
    for index in (None, 0, 7):
        full = s.apply(counts, scale, index)
        assert full.tobytes() == Sensor(cfg, (h, w), seed=11, noise=noise).apply(
            counts, scale, index).tobytes()
        for y0, y1, x0, x1 in _rois(h, w, 20, seed=0 if index is None else index):
            crop = s.apply(counts[y0:y1, x0:x1], scale, index, (y0, y1, x0, x1))
            assert crop.dtype == full.dtype
            np.testing.assert_array_equal(crop, full[y0:y1, x0:x1])
            half = counts[y0:y1, x0:x1] // 2
            np.testing.assert_array_equal(
                s.apply(counts[y0:y1, x0:x1] - half, scale, index, (y0, y1, x0, x1), base=half),
                crop)
    # each tile has its own draws (no tile repeats another's noise)
    z = s.normals(5, (0, h, 0, w))
    assert not np.array_equal(z[:TILE, :TILE], z[:TILE, TILE:2 * TILE])
    assert not np.array_equal(z[:TILE, :TILE], s.normals(6, (0, TILE, 0, TILE)))
    assert abs(float(z.mean())) < 0.02 and float(z.std()) == pytest.approx(1.0, abs=0.02)
    with pytest.raises(ValueError, match="roi"):
        s.apply(counts[:10, :10], scale, 0, (0, 10, 0, 11))


@pytest.mark.parametrize("shape", [(150, 203), (1024, 1280)])
def test_the_fixed_pattern_is_drawn_on_the_full_pixel_grid(shape):
    # the vignetting from a row and a column broadcast (np.ogrid) is the formula on every
    # pixel's own coordinates (np.mgrid, the code before 2026-11-23), to the bit
    from synth.sensor import _fixed_pattern

    cfg = synth.SensorConfig(vignetting=0.08, prnu=0.005, dsnu=3.0)
    gain, offset = _fixed_pattern(cfg, shape, 5)
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2
                                                                + ((h - 1) / 2) ** 2)
    rng = np.random.default_rng([5, 0])
    prnu, dsnu = rng.standard_normal(shape), rng.standard_normal(shape)
    assert np.array_equal(gain, np.ones(shape) * (1.0 - 0.08 * r2) * (1.0 + 0.005 * prnu))
    assert np.array_equal(offset, 3.0 * np.abs(dsnu))


@pytest.mark.parametrize("bit_depth", [8, 12])
def test_hash_sensor_kernel_is_the_per_pixel_formula(bit_depth):
    # the kernel draws a block of rows' normals phase by phase (2026-11-24): its bytes are the
    # model's formula in float32 on each pixel's own draw (Sensor.normals: one polar draw a
    # pair of pixels), for regions of odd and even starts and widths, taller than a block
    from synth.sensor import GAMMA, ROWS

    cfg = synth.SensorConfig(bit_depth=bit_depth, read_noise=8.0, black_level=3.0,
                             vignetting=0.2, prnu=0.01, dsnu=5.0)
    h, w = ROWS * 3 + 7, 203
    scale = 1000
    counts = np.random.default_rng(5).integers(-3, scale + 4, (h, w)).astype(np.int32)
    s = Sensor(cfg, (h, w), seed=13)
    lut = ((np.arange(scale + 1) / scale) ** GAMMA * (cfg.full_well * cfg.exposure
                                                    / cfg.reference_exposure)).astype(np.float32)
    k = np.float32(cfg.gain * cfg.max_dn / cfg.full_well)
    for index in (None, 4):
        for y0, y1, x0, x1 in [(0, h, 0, w), (1, h, 1, w), (3, 70, 0, 1), (5, 6, 7, 9),
                               (0, h, 2, 5), (40, h - 1, 11, 200)]:
            e = lut[np.clip(counts[y0:y1, x0:x1], 0, scale)]
            e = e * s.gain_map[y0:y1, x0:x1] + s.offset_map[y0:y1, x0:x1]
            var = np.maximum(e, np.float32(0)) + np.float32(cfg.read_noise ** 2)
            e = e + np.sqrt(var) * s.normals(index, (y0, y1, x0, x1))
            want = np.clip(np.rint(e * k + np.float32(cfg.black_level)), 0, cfg.max_dn)
            got = s.apply(counts[y0:y1, x0:x1], scale, index, (y0, y1, x0, x1))
            np.testing.assert_array_equal(got, want.astype(cfg.dtype))
            # the levels as a difference over a base (a recording's background), summed in
            # the kernel
            base = np.random.default_rng(y0 + x1).integers(0, 600, (y1 - y0, x1 - x0),
                                                           dtype=np.int32)
            got = s.apply(counts[y0:y1, x0:x1] - base, scale, index, (y0, y1, x0, x1),
                          base=base)
            np.testing.assert_array_equal(got, want.astype(cfg.dtype))


def test_hash_noise_is_a_function_of_seed_frame_and_pixel():
    # "hash/1": a pixel's draw depends on (seed, frame, pixel) only - not on the frame's size or
    # the region asked for - and the draws are independent standard normals
    cfg = synth.noise_preset("realistic")
    a = Sensor(cfg, (300, 401), seed=3).normals(2, (0, 300, 0, 401))
    b = Sensor(cfg, (64, 64), seed=3).normals(2, (0, 64, 0, 64))
    np.testing.assert_array_equal(a[:64, :64], b)
    assert not np.array_equal(a, Sensor(cfg, (300, 401), seed=4).normals(2, (0, 300, 0, 401)))
    c = Sensor(cfg, (300, 401), seed=3).normals(3, (0, 300, 0, 401))
    bg = Sensor(cfg, (300, 401), seed=3).normals(None, (0, 300, 0, 401))
    z = a.astype(np.float64).ravel()
    n = z.size  # 120300 draws: a moment is off by more than 5 of its standard errors by chance
    assert abs(z.mean()) < 5 / np.sqrt(n) and abs(z.std() - 1) < 5 * np.sqrt(0.5 / n)
    assert abs(np.mean(z ** 4) - 3) < 5 * np.sqrt(96 / n)  # Gaussian kurtosis
    assert abs(np.mean(np.abs(z) > 3) - 0.0027) < 5 * np.sqrt(0.0027 / n)  # tails
    for u, v in [(a[:, 0::2], a[:, 1::2][:, :200]), (a[:-1], a[1:]), (a, c), (a, bg)]:
        # the two draws of a pair, vertical neighbours, other frames, the background
        u, v = u[:, :200].ravel(), v[:, :200].ravel()
        assert abs(np.corrcoef(u, v)[0, 1]) < 5 / np.sqrt(u.size)


def test_store_chunks_read_directly_and_old_stores_keep_their_noise(rec_path, tmp_path):
    import shutil

    import zarr

    from synth.store import SynthFrames

    frames = synth.open_recording(rec_path).frames
    assert frames.noise == "hash/1" and frames._chunk_file is not None
    via_zarr = SynthFrames(zarr.open_group(str(rec_path), mode="r"))
    via_zarr._chunk_file = None  # what any other store gets
    for i in range(len(frames)):
        np.testing.assert_array_equal(frames.clean_counts(i), via_zarr.clean_counts(i))
        assert frames[i].tobytes() == via_zarr[i].tobytes()
    # a store rendered before "hash/1" (no sensor_noise attribute) is read with its tiles
    old = tmp_path / "old.zarr"
    shutil.copytree(rec_path, old)
    g = zarr.open_group(str(old), mode="r+")
    del g.attrs["sensor_noise"]
    f = synth.open_recording(old).frames
    assert f.noise == "tiles/1"
    tiles = Sensor(f.sensor_config, f.shape[1:], f.seed, noise="tiles/1")
    assert f[2].tobytes() == tiles.apply(f.clean_counts(2), int(f.frame_scale), 2).tobytes()
    assert f[2].tobytes() != frames[2].tobytes()
    g.attrs["sensor_noise"] = "hash/9"
    with pytest.raises(synth.SynthError, match="hash/9"):
        synth.open_recording(old)


def test_read_a_region_is_the_crop_of_the_frame(rec_path):
    from rollfric.io import readers as io

    frames = synth.open_recording(rec_path).frames
    src = io.open_recording(rec_path)  # through rollfric's reader and the entry point
    for i in (0, 3, len(frames) - 1):
        full = frames[i]
        for roi in _rois(128, 160, 15, seed=i):
            y0, y1, x0, x1 = roi
            crop = frames.read(i, roi)
            assert crop.dtype == np.uint8
            np.testing.assert_array_equal(crop, full[y0:y1, x0:x1])
            np.testing.assert_array_equal(src.read(i, roi), crop)
            np.testing.assert_array_equal(frames.clean_counts(i, roi),
                                          frames.clean_counts(i)[y0:y1, x0:x1])
    # same seed, another reader, region first: the same bytes
    other = synth.open_recording(rec_path).frames
    assert other.read(4, (10, 90, 20, 150)).tobytes() == frames[4][10:90, 20:150].tobytes()
    for bad in [(0, 0, 0, 5), (0, 129, 0, 5), (-1, 5, 0, 5), (5, 3, 0, 5)]:
        with pytest.raises(IndexError, match="roi"):
            frames.read(0, bad)
    with pytest.raises(TypeError, match="roi"):
        frames.read(0, (0, 5))


def test_noise_none_is_the_quantised_clean_render(rec_path):
    rec = synth.open_recording(rec_path)
    s = Sensor(synth.noise_preset("none"), rec.frames.shape[1:], seed=0)
    clean = rec.frames.clean(2)
    out = s.apply(rec.frames.clean_counts(2), int(rec.frames.frame_scale), 2)
    np.testing.assert_array_equal(out, np.clip(np.rint(clean ** 2.2 * 255), 0, 255))


def test_entry_point_reads_the_store(rec_path):
    import zarr

    (ep,) = [e for e in entry_points(group="rollfric.zarr_readers") if e.name == "synth"]
    open_frames = ep.load()
    assert open_frames is synth.store.open_frames
    src = open_frames(zarr.open_group(str(rec_path), mode="r"))
    rec = synth.open_recording(rec_path)
    assert len(src) == len(rec) and src.shape == rec.frames.shape and src.dtype == np.uint8
    assert src[3].tobytes() == rec.frames[3].tobytes()
    assert src.background.shape == (128, 160) and isinstance(src.attrs, dict)
    assert src.attrs["setup"]["ball"]["diameter_mm"] == pytest.approx(10.0)
    # not a synth store: None, so other readers get their turn
    other = zarr.open_group(str(rec_path.parent / "other.zarr"), mode="w")
    other.attrs["format"] = "something-else"
    assert open_frames(other) is None


def test_two_processes_render_the_same_bytes(traj, rec_path, tmp_path):
    out = synth.render(traj, tmp_path / "par.zarr", scene=synth.SceneConfig(camera=CAM),
                       sensor=synth.noise_preset("realistic"), seed=7, workers=2,
                       frames=len(traj))
    a, b = synth.open_recording(rec_path).frames, synth.open_recording(out).frames
    for i in range(len(a)):
        assert a[i].tobytes() == b[i].tobytes()


def test_render_processes_draw_the_same_bytes(tmp_path):
    """A recording of 5 batches on 2 render processes (forked from the fork server where there
    is one: synth.pool.pool_context) holds the bytes of the recording one process draws
    (the recording above is too short for a second process)."""
    import zarr

    from synth import pipeline

    tr = sim.simulate(sim.Scenario(theta0=0.03, duration=0.079))
    assert -(-len(tr) // pipeline.BATCH) == 5
    kw = {"scene": synth.SceneConfig(camera=CAM), "sensor": synth.noise_preset("realistic"),
          "seed": 7}
    ref = synth.render(tr, tmp_path / "one.zarr", workers=1, **kw)
    sched: dict = {}
    out = synth.render(tr, tmp_path / "two.zarr", workers=2, schedule=sched, **kw)
    # the schedule lists each batch once, from at most 2 processes, after the start
    assert sorted(b[0] for b in sched["batches"]) == list(range(0, len(tr), pipeline.BATCH))
    assert len({b[1] for b in sched["batches"]}) <= 2 and sched["workers"] == 2
    assert all(sched["start"] <= sched["submitted"] <= b[2] <= b[3] for b in sched["batches"])
    np.testing.assert_array_equal(zarr.open_group(str(ref), mode="r")["clean_diff"][...],
                                  zarr.open_group(str(out), mode="r")["clean_diff"][...])
    # the background the processes read (without zarr) is not left in the store
    assert not (out / pipeline.BACKGROUND_FILE).exists()
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in ref.iterdir())
    a, b = synth.open_recording(ref), synth.open_recording(out)
    for i in range(len(tr)):
        assert a.frames[i].tobytes() == b.frames[i].tobytes()


def test_export_like_a_lab_camera(rec_path, tmp_path):
    import cv2
    import pandas as pd
    import tifffile

    from rollfric.setup.model import load_setup
    from synth.export import export_recording

    d = export_recording(rec_path, tmp_path / "exp")
    rec = synth.open_recording(rec_path)
    stack = tifffile.imread(d / "frames.tif")
    assert stack.shape == rec.frames.shape
    np.testing.assert_array_equal(stack[4], rec.frames[4])
    # lossless deflate on horizontal differences, every frame the recording's, and rollfric
    # reads it (decoded through imagecodecs) as the same frames
    with tifffile.TiffFile(d / "frames.tif") as tif:
        page = tif.pages[0]
        assert page.compression == tifffile.COMPRESSION.ADOBE_DEFLATE
        assert page.predictor == tifffile.PREDICTOR.HORIZONTAL
    assert (d / "frames.tif").stat().st_size < 0.8 * stack.nbytes
    src = rollfric.io.readers.open_recording(d / "frames.tif")
    for i in range(len(rec)):
        np.testing.assert_array_equal(stack[i], rec.frames[i])
        np.testing.assert_array_equal(src[i], rec.frames[i])
    np.testing.assert_array_equal(cv2.imread(str(d / "background.png"), cv2.IMREAD_UNCHANGED),
                                  rec.background)
    setup = load_setup(d / "setup.toml")
    assert setup.center_px == (80.0, -500.0) and setup.fps == 1000.0
    truth = pd.read_csv(d / "truth.csv")
    assert list(truth.columns) == ["frame", "t_s", "x_px", "y_px", "theta_rad"]
    np.testing.assert_allclose(truth.x_px, rec.truth.x_px, rtol=1e-9)


def test_bad_inputs_are_refused(traj, tmp_path):
    with pytest.raises(synth.SynthError, match="lighting preset"):
        synth.lighting_preset("disco")
    with pytest.raises(synth.SynthError, match="bit_depth"):
        synth.SensorConfig(bit_depth=9)
    with pytest.raises(synth.SynthError, match="frames"):
        synth.render(traj, tmp_path / "x.zarr", frames=0)
    with pytest.raises(synth.SynthError, match="not found"):
        synth.render(tmp_path / "missing.csv", tmp_path / "x.zarr")
    assert not (tmp_path / "x.zarr").exists()
    with pytest.raises(synth.SynthError, match="supersample"):
        synth.SceneConfig(supersample=0)
    cam = dataclasses.replace(CAM, width=64)
    assert cam.width == 64


def test_rollfric_reads_the_recording_through_its_io(rec_path):
    io = pytest.importorskip("rollfric.io.readers")
    src = io.open_recording(rec_path)
    rec = synth.open_recording(rec_path)
    assert len(src) == len(rec)
    assert src[2].tobytes() == rec.frames[2].tobytes()
    assert src.attrs["setup"] == rec.attrs["setup"]


def test_chunk_writer_writes_the_files_zarr_writes(tmp_path):
    """Frames written chunk by chunk from patches (the render workers' way) are the files zarr
    writes for the same frames (empty chunks absent in both), and read back the same."""
    import zarr
    from zarr.codecs import ZstdCodec

    from synth.chunks import chunk_files, chunk_writer

    g = zarr.open_group(str(tmp_path / "w.zarr"), mode="w")
    kw = dict(shape=(3, 300, 260), dtype="int16", chunks=(1, 128, 128), fill_value=0,
              chunk_key_encoding={"name": "v2", "separator": "."},
              compressors=[ZstdCodec(level=1)])
    ours, theirs = g.create_array("ours", **kw), g.create_array("theirs", **kw)
    write = chunk_writer(g, ours)
    rng = np.random.default_rng(1)
    # across chunk borders, on the frame's ragged edge, overlapping, and an all-zero patch
    boxes = [(130, 120, 60, 20), (200, 250, 60, 50), (140, 125, 30, 10), (5, 5, 20, 20)]
    for i in range(3):
        full = np.zeros((300, 260), np.int16)
        patches = []
        for k, (x0, y0, w, h) in enumerate(boxes):
            v = rng.integers(-900, 900, (h, w)) * (k != 3)
            patches.append(((x0, y0, w, h), v))
            full[y0:y0 + h, x0:x0 + w] = v[:300 - y0, :260 - x0]
        write(i, patches)
        theirs[i] = full
        np.testing.assert_array_equal(ours[i], full)
        read = chunk_files(g, ours)
        np.testing.assert_array_equal(read(i, (100, 290, 90, 259)), full[100:290, 90:259])
    names = sorted(p.name for p in (tmp_path / "w.zarr" / "ours").iterdir()
                   if p.name != "zarr.json")
    assert names == sorted(p.name for p in (tmp_path / "w.zarr" / "theirs").iterdir()
                           if p.name != "zarr.json")
    assert "0.0.0" not in names and "0.0.1" in names  # the all-zero chunk is not written
    for name in names:
        assert (tmp_path / "w.zarr" / "ours" / name).read_bytes() == \
            (tmp_path / "w.zarr" / "theirs" / name).read_bytes()


def test_a_corrupt_chunk_stops_the_measurement_with_a_message(rec_path, tmp_path, capsys):
    import re
    import shutil

    from rollfric.cli.main import main
    from rollfric.errors import InputError
    from rollfric.measurement import measure

    bad = tmp_path / "bad.zarr"
    shutil.copytree(rec_path, bad)
    def frame_of(p):  # chunk keys "5.0.1" or "c/5/0/1"
        keys = [k for k in re.split(r"[./]", p.relative_to(bad / "clean_diff").as_posix())
                if k != "c"]
        return keys[0] if len(keys) == 3 else None

    frame5 = [p for p in (bad / "clean_diff").rglob("*") if p.is_file() and frame_of(p) == "5"]
    assert frame5
    for p in frame5:
        p.write_bytes(b"not zstd" * 10)
    with pytest.raises(InputError, match="frame 5's chunk is corrupt"):
        measure(bad, fit=False)
    # the command: exit 2, the message, nothing written (track: 12 frames are too few for
    # measure, which refuses them on opening)
    out = tmp_path / "out"
    assert main(["track", str(bad), "--out", str(out), "--no-progress"]) == 2
    assert "frame 5's chunk is corrupt" in capsys.readouterr().err
    assert not out.exists()


def test_scratch_dir_only_with_room(tmp_path, monkeypatch):
    """Temporary recordings go to the RAM-backed folder only when it exists, is writable and
    has room for the frames; else to the system's temporary folder (None)."""
    import shutil
    from collections import namedtuple

    import synth.store as store

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(store, "SCRATCH", str(tmp_path))
    room = 4001 * store.SCRATCH_FRAME_BYTES + store.SCRATCH_SPARE_BYTES
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(2 * room, 0, room))
    assert store.scratch_dir(4001) == str(tmp_path)
    assert store.scratch_dir(4002) is None
    monkeypatch.setattr(store, "SCRATCH", str(tmp_path / "missing"))
    assert store.scratch_dir(10) is None


def test_the_same_case_twice_gives_every_file_the_same_bytes(tmp_path):
    """Two simulations of one scenario (their wall times differ) rendered with one seed: every
    file of the two stores is the same, attributes included (the simulation's wall time was
    stored and made the top zarr.json differ from run to run)."""
    outs = []
    for name in ("a", "b"):
        tr = sim.simulate(sim.Scenario(theta0=0.03, duration=0.006))
        tr.meta["wall_time_s"] = {"a": 0.25, "b": 0.5}[name]  # as two runs' clocks would differ
        outs.append(synth.render(tr, tmp_path / f"{name}.zarr",
                                 scene=synth.SceneConfig(camera=CAM),
                                 sensor=synth.noise_preset("realistic"), seed=7, workers=1))
    files = [sorted(p.relative_to(o) for p in o.rglob("*") if p.is_file()) for o in outs]
    assert files[0] == files[1] and len(files[0]) > 3
    for rel in files[0]:
        assert (outs[0] / rel).read_bytes() == (outs[1] / rel).read_bytes(), rel
    assert "wall_time_s" not in synth.open_recording(outs[0]).attrs["engine_meta"]


def test_a_chunk_file_larger_than_any_chunk_is_read_whole(rec_path, tmp_path):
    # one read of a chunk's bound holds any chunk file; a larger one (not a chunk) is read to
    # its end and refused as corrupt, a valid one padded by a skippable zstd frame is read
    import shutil
    import struct

    bad = tmp_path / "big.zarr"
    shutil.copytree(rec_path, bad)
    frames = synth.open_recording(bad).frames
    files = sorted(p for p in (bad / "clean_diff").rglob("*") if p.is_file())
    good = files[0]
    data = good.read_bytes()
    want = frames._chunk_file  # reads the files as they are now
    key = good.relative_to(bad / "clean_diff").as_posix().replace("c/", "").replace("/", ".")
    i, cy, cx = (int(v) for v in key.split("."))
    box = (cy * 128, cy * 128 + 16, cx * 128, cx * 128 + 16)
    before = want(i, box)
    pad = 200_000
    good.write_bytes(data + struct.pack("<II", 0x184D2A50, pad) + bytes(pad))
    np.testing.assert_array_equal(want(i, box), before)
    good.write_bytes(b"not zstd" * 30_000)
    with pytest.raises(synth.SynthError, match=f"frame {i}'s chunk is corrupt"):
        want(i, box)
