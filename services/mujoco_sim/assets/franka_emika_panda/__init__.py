"""MuJoCo Menagerie's Franka Emika Panda (Apache-2.0, see LICENSE and NOTICE); data only."""
