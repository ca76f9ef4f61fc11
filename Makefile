# Two commands on a fresh machine: `make run` and `make test`. Each creates .venv if missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
HOST ?= 127.0.0.1
PORT ?= 8000

# Python compiles to bytecode (and pytest caches its rewritten test modules) unless told not to:
# a shell that sets PYTHONDONTWRITEBYTECODE made every run rewrite ~450 plugin and test modules
# again (6 s per xdist worker).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test check lint typecheck openapi bench screenshots demo clean

# uv installs the project and its dependencies (4 s on a fresh clone here; pip took 56 s). Then
# the bytecode of what is imported is written once, by two processes: without it both xdist
# workers, pytest's controller and every server compiled the same modules at once (the first
# `make check` of a fresh clone took 107 s of pytest, 76 s with the bytecode). The first imports
# the servers', publishers' and browser tests' modules; the second collects the fuzzing module,
# which loads pytest's plugins and so writes the assertion-rewritten bytecode of hypothesis and
# schemathesis (pytest rewrites a plugin's whole package: 355 modules, 5 s of CPU per process).
# Only what is imported: `uv pip install --compile-bytecode` compiled all 8,500 modules of the
# venv (18 s on 2 cores here), plotly's 1,500, pip's and mypy's among them, and none of the
# rewritten ones. (What these miss is compiled on its first import.)
WARM_IMPORTS := app.main, app.cli, app.storage.backup, app.publish.runner, app.publish.mqtt, app.publish.opcua_sink, uvicorn, alembic.command, playwright.sync_api, yourdfpy, scipy.stats, scipy.optimize
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet 'uv>=0.5'
	$(BIN)/uv pip install --quiet --python $(BIN)/python -e '.[dev]'
	$(BIN)/python -c 'import $(WARM_IMPORTS)' & imports=$$!; \
	$(BIN)/pytest -qq --collect-only -p no:cacheprovider tests/api/test_schemathesis.py \
	&& wait $$imports
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/tcpcal db upgrade
	@echo ""
	@echo "tcpcal serving on http://$(HOST):$(PORT) (SQLite file var/tcpcal.sqlite3)"
	@echo "Get an API key:  $(BIN)/tcpcal keys create --scope admin --name me"
	@echo "  or start with: TCPCAL_BOOTSTRAP_ADMIN_KEY=<a long secret> make run"
	@echo "Then: curl -H 'Authorization: Bearer <key>' http://$(HOST):$(PORT)/v1/robots"
	@echo "  or open the console, http://$(HOST):$(PORT)/, and sign in with the key"
	@echo ""
	$(BIN)/tcpcal serve --host $(HOST) --port $(PORT)

lint: $(STAMP)
	$(BIN)/ruff check app testbed tests bench scripts migrations
	$(BIN)/ruff format --check app testbed tests bench scripts migrations
	$(BIN)/lint-imports

typecheck: $(STAMP)
	$(BIN)/mypy

# The whole suite: every test, live servers, browsers and killed processes included. (The
# committed openapi.json is checked byte for byte by tests/test_openapi.py, which is what
# `tcpcal openapi --check` does.)
# --dist loadscope: each module on one xdist worker, so that a server or a seeded fleet its
# tests share (a module fixture) starts once and not once on each worker; modules in the order
# collected, so the live ones run mid-suite and the tail is short modules. (loadgroup with
# xdist_group marks would group finer, but pytest 9.2 made it group nothing: pytest-xdist#1386.)
PYTEST := $(BIN)/pytest -q -n 2 --dist loadscope --no-loadscope-reorder --durations=20

# The OPC UA server is tested with a client of another implementation, node-opcua, installed
# from the lock file in tests/opcua_client. Without npm those tests skip (under CI they fail).
NODE_CLIENT := tests/opcua_client
$(NODE_CLIENT)/node_modules/.installed: $(NODE_CLIENT)/package-lock.json
	@if command -v npm >/dev/null 2>&1; then \
		(cd $(NODE_CLIENT) && npm ci --no-audit --no-fund) && touch $@; \
	else echo "npm not found: the node-opcua client tests will be skipped (apt-get install npm)"; fi

test: lint $(NODE_CLIENT)/node_modules/.installed
	$(call beside_mypy,$(PYTEST))

# The fast tier for the edit-test loop (under 2 minutes on 2 cores): lint, types and every
# test that starts no server, browser or process of its own (markers in pyproject.toml).
check: lint
	$(call beside_mypy,$(BIN)/pytest -q -n 2 -m "not live and not browser and not kills")

# $(call beside_mypy,TESTS): mypy runs beside the tests, its report printed after theirs. The
# tests leave the cores idle for stretches (browsers and brokers waited on: /proc/stat sampled
# every 5 s gave 88 % busy over `make test`), where a cold mypy's 25 s of CPU fit; after them it
# added its whole 25 s. Either failing fails the target.
define beside_mypy
@$(BIN)/mypy > $(VENV)/typecheck.log 2>&1 & typecheck=$$!; \
echo 'mypy (beside the tests) and: $(1)'; \
$(1); tests=$$?; \
wait $$typecheck; types=$$?; \
echo "mypy:"; cat $(VENV)/typecheck.log; \
test $$tests -eq 0 && test $$types -eq 0
endef

openapi: $(STAMP)
	$(BIN)/tcpcal openapi

bench: $(STAMP)
	$(BIN)/python -m bench.accuracy
	$(BIN)/python -m bench.conventions
	$(BIN)/python -m bench.planner
	$(BIN)/python -m bench.solver_speed
	$(BIN)/python -m bench.wrk_load
	$(BIN)/python -m bench.scale

screenshots: $(STAMP)
	$(BIN)/python scripts/screenshots.py

demo: $(STAMP)
	mkdir -p var
	TCPCAL_DATABASE_URL=sqlite:///var/demo.sqlite3 $(BIN)/tcpcal demo
	@echo "serve it: TCPCAL_DATABASE_URL=sqlite:///var/demo.sqlite3 $(BIN)/tcpcal serve --port 8001"
	@echo "  (port 8001: make run's server may hold 8000), then open http://127.0.0.1:8001/"

clean:
	rm -rf $(VENV) var .pytest_cache .mypy_cache .ruff_cache .hypothesis
