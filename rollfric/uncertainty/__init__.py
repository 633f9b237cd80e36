"""How far mu can be trusted: the uncertainty budget, the quality verdicts, repeated runs
combined."""
