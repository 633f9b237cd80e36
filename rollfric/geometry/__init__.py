"""The trough's geometry in the image: its axis, its contour's shape, the camera's depth."""
