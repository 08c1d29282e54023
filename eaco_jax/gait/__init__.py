"""Gait optimisation: walk engine, rollouts on MJX / native MuJoCo, fitness."""
