"""Benchmarks of the library and of the whole system (wire, hands, latency, replay, bridge)."""
