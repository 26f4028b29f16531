"""Transfer of a task descriptor to a similar object by registering the object models (issue 6)."""
