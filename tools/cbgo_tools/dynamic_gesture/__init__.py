"""Offline tools of the dynamic-gesture service: training, benchmarks, real-people trials."""
