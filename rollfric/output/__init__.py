"""Where results go: output folders written whole, figures of the measurement."""
