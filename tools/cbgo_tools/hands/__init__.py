"""Offline tools of the hand model: calibrating its poses against real recordings."""
