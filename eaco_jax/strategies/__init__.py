"""Colony strategies: one module per algorithm."""
