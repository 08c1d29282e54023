"""Gait optimisation: walk engine and leg IK, rollouts on MJX / native MuJoCo, the paper's fitness,
randomised worlds for robust fitness (``worlds``), energy and gait-quality metrics (``quality``),
validation trials and replayable export (``validate``), offscreen video (``render``)."""
