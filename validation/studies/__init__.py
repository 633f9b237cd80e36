"""Studies of the measurement: coverage of the budget, the verdicts' hit rates, the lab errors'
effect on mu."""
