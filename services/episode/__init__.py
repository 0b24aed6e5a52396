"""episode: gesture episodes, evidence, the gesture vector g, focus and metric parameters."""
