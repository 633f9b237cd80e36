"""The tutorial page's printed outputs (docs/snippets/tutorial/) are what its commands print
now: docs/scripts/tutorial.py --check runs them again and compares (timings aside)."""

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "docs" / "scripts" / "tutorial.py"


def _script():
    spec = importlib.util.spec_from_file_location("docs_tutorial", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_comparison_finds_a_changed_number_and_ignores_timings():
    t = _script()
    old = "mu = 0.007904 +- 0.00033; 2 run now in 19.6 s\n"
    assert t.differs("measure", old.replace("19.6", "35.2"), old) is None
    assert "0.007904" in t.differs("measure", old.replace("0.007904", "0.007905"), old)
    assert t.differs("measure", old.replace("mu =", "nu ="), old) is not None
    # a rendered case's numbers within 5 %
    assert t.differs("validate", old.replace("0.007904", "0.007910"), old) is None
    assert t.differs("validate", old.replace("0.007904", "0.0085"), old) is not None


@pytest.mark.slow
def test_the_committed_tutorial_outputs_match_what_its_commands_print(capsys):
    # validate and sweep render: the suite's extra (synth itself imports without it)
    missing = [m for m in ("mujoco", "pyrender", "dask", "skimage")
               if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"the validation suite's extra is not installed (no {', '.join(missing)})")
    assert _script().main(["--check"]) == 0, capsys.readouterr().out
