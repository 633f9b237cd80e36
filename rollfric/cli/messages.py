"""rollfric's messages on the command line: its loggers' records printed on stderr.

The library reports through :mod:`logging` (``logging.getLogger(__name__)`` in each module):
``info`` for what it chose or did (a median background, the trough's centre from the
contour, frames without a ball), ``warning`` for what the user should check. A program using
rollfric configures logging as it likes (unconfigured, Python prints warnings and drops
info). A command prints them with :func:`to_stderr`.
"""

from __future__ import annotations

import contextlib
import logging
import sys


class _CommandFormatter(logging.Formatter):
    def __init__(self, command: str) -> None:
        super().__init__()
        self.command = command

    def format(self, record: logging.LogRecord) -> str:
        kind = "warning: " if record.levelno >= logging.WARNING else ""
        return f"rollfric {self.command}: {kind}{record.getMessage()}"


@contextlib.contextmanager
def to_stderr(command: str, logger: str = "rollfric", level: int = logging.INFO):
    """Print the messages of ``logger`` (``level`` and up) on stderr while the block runs.

    Parameters
    ----------
    command : str
        The subcommand, named in each line: ``rollfric COMMAND: [warning: ]message``.
    logger : str
        The logger whose records (and its children's) are printed.
    level : int
        The least severe level printed.

    Yields
    ------
    logging.Handler
        The handler, removed again when the block ends.
    """
    log = logging.getLogger(logger)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_CommandFormatter(command))
    handler.setLevel(level)
    old_level, old_propagate = log.level, log.propagate
    log.addHandler(handler)
    log.setLevel(min(level, log.getEffectiveLevel()))
    log.propagate = False  # printed here, not again by a handler of the root logger
    try:
        yield handler
    finally:
        log.removeHandler(handler)
        log.setLevel(old_level)
        log.propagate = old_propagate
