"""Console scripts (like `lerobot/scripts`)."""
