"""``rollfric bench``: the speed and accuracy of every stage, measured beside the baseline a user
would pick."""
