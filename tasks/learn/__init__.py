"""Learning a task descriptor from a recording: segment, fit, assemble the chain M with extents C."""
