"""synth.pool.crash_report: a render process that crashes leaves its Python stacks on
stderr (a real segfault in a child process, faulthandler's own trigger)."""

import subprocess
import sys
import textwrap


def _crash(enable: bool) -> subprocess.CompletedProcess:
    code = textwrap.dedent(f"""
        import faulthandler
        from synth.pool import crash_report
        def render_a_batch():
            faulthandler._sigsegv()
        assert crash_report() if {enable} else True
        render_a_batch()
    """)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)


def test_a_crash_leaves_the_stack_of_the_function_that_crashed():
    out = _crash(True)
    assert out.returncode != 0
    assert "Segmentation fault" in out.stderr
    assert "render_a_batch" in out.stderr


def test_without_it_no_stack():
    out = _crash(False)
    assert out.returncode != 0
    assert "render_a_batch" not in out.stderr
