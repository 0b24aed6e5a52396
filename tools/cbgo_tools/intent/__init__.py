"""Offline tools of the intent service: benchmarks, training."""
