"""Robot models (MJCF) and their specs, shipped inside the wheel as ``eaco_jax.robots``."""

from pathlib import Path

ROBOTS_DIR = Path(__file__).resolve().parent
