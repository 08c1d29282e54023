# Two commands from a fresh clone:  `make demo` (solve a TSP, optimise a walking gait) and
# `make test`. Both create the virtual environment .venv themselves.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-all lint bench clean docs docs-api claim claims-cpu check-claims

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/eaco tsp eil51 --iterations 200 --out out/tsp
	$(BIN)/eaco gait --robot nao --init experiments/results/nao_constrained_warp/flat_r32/best_gait.json --steer --out out/gait
	$(BIN)/eaco gait-eval experiments/results/nao_constrained_warp/flat_r32/best_gait.json --horizon 20 --out out/best_gait

test: $(STAMP)
	$(BIN)/ruff check eaco_jax robots experiments tests docs
	$(BIN)/python -m pytest -m "not slow" -n 2 --durations=15 --nbmake tests notebooks

test-all: $(STAMP)
	$(BIN)/python -m pytest -n 2 --nbmake tests notebooks

docs: $(STAMP)
	$(BIN)/python docs/generate.py

# the claims manifest (experiments/claims.toml): rerun one claim's command and compare its file
# with the stated figure; rerun every CPU claim cheaper than CLAIMS_MAX_SECONDS; compare all
CLAIMS_MAX_SECONDS ?= 300
claim: $(STAMP)
	@test -n "$(ID)" || (echo "usage: make claim ID=<claim id>  (python experiments/claims.py list)"; exit 2)
	$(BIN)/python experiments/claims.py run $(ID)
claims-cpu: $(STAMP)
	$(BIN)/python experiments/claims.py cpu --max-seconds $(CLAIMS_MAX_SECONDS)
check-claims: $(STAMP)
	$(BIN)/python experiments/claims.py check

# the API reference from the docstrings (pdoc) into docs/api/; any pdoc warning fails the target
API_MODULES := eaco_jax eaco_jax.driver eaco_jax.ops eaco_jax.runs eaco_jax.sweep eaco_jax.cli \
               eaco_jax.gait eaco_jax.errors eaco_jax.outputs eaco_jax.plots
docs-api: $(STAMP)
	rm -rf docs/api
	JAX_PLATFORMS=cpu $(BIN)/python -m pdoc -o docs/api --docformat google $(API_MODULES) \
	  2> docs/api.log; status=$$?; cat docs/api.log; \
	  test $$status -eq 0 && ! grep -q "Warn" docs/api.log

clean:
	rm -rf $(VENV) out build *.egg-info
