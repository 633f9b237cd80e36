"""Reading recordings: the readers, camera file formats, the background and the camera's bit
depth."""
