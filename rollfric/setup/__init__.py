"""The lab's setup: trough, ball and camera, the TOML files that state them, the lens
calibration."""
