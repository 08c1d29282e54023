"""``python -m eaco_jax`` runs the ``eaco`` command line."""

from eaco_jax.cli import main

main()
