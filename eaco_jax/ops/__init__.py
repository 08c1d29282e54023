"""Building blocks of the colonies: construction, pheromone rules, genetic operators, local search,
constraint handling (small pure functions, each testable alone, composed by the strategies)."""
