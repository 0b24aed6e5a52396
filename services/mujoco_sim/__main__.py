"""`python -m cbgo.services.mujoco_sim` runs the service."""

from cbgo.services.mujoco_sim.main import main

main()
