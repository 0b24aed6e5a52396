"""static-gesture: per-frame static gesture probabilities from a Bayesian MLP."""
