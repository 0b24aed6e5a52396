"""The cbgo services, one subpackage each; every one runs as its own process."""
