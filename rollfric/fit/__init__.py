"""Fitting mu to theta(t): the equation of motion, the air, the least-squares and thesis fits."""
