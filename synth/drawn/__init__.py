"""Frames drawn analytically with an exact sub-pixel truth (no renderer): discs, mirror balls,
shadowgraphs."""
