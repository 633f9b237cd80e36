"""The lab's faults with a known truth: glitched frames, a moved or turned camera, faulty drawn
recordings."""
