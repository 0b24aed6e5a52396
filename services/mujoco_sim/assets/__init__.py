"""Vendored model data of mujoco-sim (a package only so that wheels ship its files)."""
