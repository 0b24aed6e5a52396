"""camera-bridge's offline tools: the benchmark (`cbgo bench camera`)."""
