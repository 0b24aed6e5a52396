"""The `cbgo` command line, one module per verb."""
