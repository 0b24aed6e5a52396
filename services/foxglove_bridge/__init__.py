"""foxglove-bridge: the live cbgo traffic as a Foxglove WebSocket server."""
