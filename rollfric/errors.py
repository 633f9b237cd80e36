"""The one exception type for bad input, shared by every stage and the command line."""


class InputError(ValueError):
    """Input that cannot be measured, simulated or rendered: the message names the culprit.

    The command line prints the message and exits with status 2, writing nothing. Every
    stage's own bad-input errors (``SetupError``, :class:`~rollfric.io.source.RecordingError`,
    ...) are subclasses.

    Examples
    --------
    >>> import rollfric
    >>> try:
    ...     rollfric.thesis_setup("9mm")
    ... except rollfric.InputError as exc:
    ...     print(exc)
    unknown thesis ball '9mm' (known: 1.58mm, 10mm, 12.69mm)
    """
