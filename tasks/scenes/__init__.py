"""Built-in demonstration scenes after the paper's experiments (issue 3)."""
