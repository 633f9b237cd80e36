"""What the fork server of synth's render processes imports (:func:`synth.pool.pool_context`):
importing this module runs :func:`synth.pool.preload`, which loads the modules a render process
needs (:data:`synth.pool.PRELOAD`) once, in the server its processes are forked from."""

from __future__ import annotations

from synth import pool

pool.preload()
