"""Offline tools of the static-gesture service: benchmarks, cross-validation, scoring takes."""
