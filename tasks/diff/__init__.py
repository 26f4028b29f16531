"""What changed between two task descriptors (``pbd diff``)."""
