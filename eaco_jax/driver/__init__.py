"""The run driver: compiled chunks of ask/evaluate/tell, stop rules, checkpoints."""
