"""validation.make_sample makes the sample recording shipped in rollfric/data/sample again,
byte for byte, from its seed."""

import pytest

from rollfric.sample import sample_path
from validation.make_sample import make_sample


@pytest.mark.slow
def test_make_sample_remakes_the_shipped_sample_byte_for_byte(tmp_path):
    out = make_sample(tmp_path / "sample", seed=0)
    for name in ("frames.tif", "setup.toml", "truth.json", "truth.csv"):
        assert (out / name).read_bytes() == sample_path(name).read_bytes(), name
