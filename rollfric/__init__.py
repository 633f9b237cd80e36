

def __getattr__(name):
    # rollfric.measure(recording, setup, background=None, method="subpixel", ...)
    #     -> (track, info, fit)
    # imported lazily so that `import rollfric` stays light
    if name == "measure":
        from rollfric.track import measure

        return measure
    raise AttributeError(f"module 'rollfric' has no attribute {name!r}")
