"""Compressed video: synth writes MJPEG (.avi) and H.264 (.mp4) with PyAV (synth.video),
rollfric reads them back with OpenCV (rollfric.io.readers.VideoSource); the case keys render.video
and
render.timing."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("av")

from rollfric.io import readers as io  # noqa: E402
from synth.video import VideoSpec, write_video  # noqa: E402
from tests.measure_data import make_recording  # noqa: E402


@pytest.fixture(scope="module")
def drawn():
    return make_recording(120, mu=0.02, theta0=0.5, fps=200.0, noise=1.0, seed=3)


def test_mjpeg_frames_are_the_jpegs_of_that_quality(tmp_path, drawn):
    import cv2

    path = write_video(drawn.frames, tmp_path / "v.avi", VideoSpec("mjpeg", 75), 200.0)
    src = io.open_recording(path)
    assert len(src) == 120 and src.shape[1:] == drawn.frames[0].shape
    assert src.dtype == np.uint8 and src.fps == 200.0
    for i in (0, 57, 119):
        ref = cv2.imdecode(cv2.imencode(".jpg", drawn.frames[i],
                                        [cv2.IMWRITE_JPEG_QUALITY, 75])[1], cv2.IMREAD_GRAYSCALE)
        # FFmpeg's and libjpeg's inverse DCTs round apart by at most one level
        assert np.abs(src[i].astype(int) - ref).max() <= 1


@pytest.mark.parametrize("codec,qualities", [("mjpeg", (95, 75, 50)), ("h264", (18, 23, 28))])
def test_lower_quality_changes_the_pixels_more(tmp_path, drawn, codec, qualities):
    errs = []
    for q in qualities:
        spec = VideoSpec(codec, q)
        src = io.open_recording(write_video(drawn.frames[:40], tmp_path / f"{q}{spec.suffix}",
                                            spec, 200.0))
        assert len(src) == 40
        errs.append(np.mean([np.abs(src[i].astype(float) - drawn.frames[i]).mean()
                             for i in range(40)]))
    assert errs[0] < errs[1] < errs[2]
    assert errs[0] < 2.0  # the best setting: within about a level of the 1-level noise


def test_a_playback_rate_is_reported_and_the_setup_rate_used(tmp_path, drawn):
    from rollfric import measurement as track_mod

    path = write_video(drawn.frames, tmp_path / "v.mp4", VideoSpec("h264", 18,
                                                                    playback_fps=30.0), 200.0)
    src = io.open_recording(path)
    assert src.fps == pytest.approx(30.0)
    bg = io.open_recording(write_video([drawn.background], tmp_path / "bg.mp4",
                                       VideoSpec("h264", 18), 200.0))[0]
    df, info, res = track_mod.measure(src, drawn.setup, bg)
    assert any("30 frames/s" in w and "camera.fps" in w for w in info.warnings)
    np.testing.assert_allclose(df["t_s"].to_numpy(), np.arange(120) / 200.0, atol=1e-12)
    # the centres through H.264 at crf 18 stay within 0.15 px of the drawn ones
    found = df["found"].to_numpy() == 1
    err = np.hypot(df["x_px"].to_numpy()[found] - drawn.centers[found, 0],
                   df["y_px"].to_numpy()[found] - drawn.centers[found, 1])
    assert found.sum() >= 115 and np.sqrt(np.mean(err ** 2)) < 0.15


_WRITE_IN_CHILD = """
import os, sys
import numpy as np
from synth.video import VideoSpec, write_video
os.sched_setaffinity(0, {int(c) for c in sys.argv[2].split(",")})
frames = np.load(sys.argv[1])
write_video(frames, sys.argv[3], VideoSpec("h264", 18), 200.0)
"""


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_h264_bytes_do_not_depend_on_the_machines_cpus(tmp_path, drawn):
    # x264 takes its thread count from the CPUs it may use unless told; the file says which
    import os
    import subprocess
    import sys

    np.save(tmp_path / "f.npy", np.stack(drawn.frames[:60]))
    cpus = sorted(os.sched_getaffinity(0))
    out = {}
    for name, use in (("one", cpus[:1]), ("all", cpus)):
        subprocess.run([sys.executable, "-c", _WRITE_IN_CHILD, str(tmp_path / "f.npy"),
                        ",".join(map(str, use)), str(tmp_path / f"{name}.mp4")], check=True,
                       env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
        out[name] = (tmp_path / f"{name}.mp4").read_bytes()
    from synth.video import H264_THREADS

    assert f" threads={H264_THREADS} ".encode() in out["one"]
    assert out["one"] == out["all"]


def test_h264_bytes_are_the_same_every_time(tmp_path, drawn):
    # x264's macroblock tree gave other P frames from a process's second encoder on (memory an
    # earlier encoder left): the same frames, written three times after another video, are
    # the same bytes
    write_video(drawn.frames[60:], tmp_path / "other.mp4", VideoSpec("h264", 23), 200.0)
    got = {(write_video(drawn.frames[:60], tmp_path / f"{k}.mp4", VideoSpec("h264", 18),
                        200.0)).read_bytes() for k in range(3)}
    assert len(got) == 1


@pytest.mark.parametrize("bad", [dict(codec="vp9"), dict(codec="mjpeg", quality=0),
                                 dict(codec="h264", quality=60),
                                 dict(codec="mjpeg", quality=75, playback_fps=0.0)])
def test_video_spec_refuses_bad_values(bad):
    from synth.config import SynthError

    with pytest.raises(SynthError):
        VideoSpec(**bad)


def test_case_keys_for_timing_and_video():
    from validation.case import CaseError, case_from_dict
    from validation.case_dict import small_case_dict

    d = small_case_dict()
    d["render"]["timing"] = {"jitter_us": 5, "dropped": [10, 20], "timestamps": True}
    d["render"]["video"] = {"codec": "h264", "quality": 23}
    c = case_from_dict(d)
    assert c.timing.jitter == pytest.approx(5e-6) and c.timing.dropped == (10, 20)
    assert c.timing.timestamps and c.video == VideoSpec("h264", 23)
    for key, table, word in [("timing", {"jitter": 5.0}, "jitter"),
                             ("timing", {"dropped": [1.5]}, "dropped"),
                             ("timing", {"drop_rate": 0.9}, "drop_rate"),
                             ("video", {"codec": "vp9"}, "codec"),
                             ("video", {"codec": "mjpeg", "quality": 0}, "quality")]:
        d = small_case_dict()
        d["render"][key] = table
        with pytest.raises(CaseError, match=word):
            case_from_dict(d)
