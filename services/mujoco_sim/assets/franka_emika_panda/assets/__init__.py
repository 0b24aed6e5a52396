"""Meshes of the Panda model; data only."""
