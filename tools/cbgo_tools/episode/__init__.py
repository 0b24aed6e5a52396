"""Offline tools of the episode service: benchmarks."""
