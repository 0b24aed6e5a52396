"""Offline tools of the web service: benchmarks."""
