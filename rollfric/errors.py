"""The one exception type for bad input, shared by every stage and the command line."""


class InputError(ValueError):
    """Input that cannot be measured, simulated or rendered: the message names the culprit.

    The command line prints the message and exits with status 2, writing nothing.
    """
