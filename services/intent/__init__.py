"""intent: the intended action, object and params from a gesture vector and its context."""
