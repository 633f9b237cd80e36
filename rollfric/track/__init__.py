"""From a recording to the track theta(t): the tracking loop and the checks on each frame."""
