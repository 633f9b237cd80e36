"""The simulation stage's error: bad input to a scenario (exit status 2 in the CLI)."""

from rollfric.errors import InputError


class ScenarioError(InputError):
    """A scenario that cannot be simulated (the message names the bad input)."""
