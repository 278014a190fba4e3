# The README's two set-up commands: `make run` and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
HOST ?= 127.0.0.1
PORT ?= 8000

.PHONY: run test lint audit audit-code audit-deps format typecheck bench accuracy clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed-run: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@ $(VENV)/.installed-run

run: $(VENV)/.installed-run
	$(BIN)/vigil serve --host $(HOST) --port $(PORT)

test: $(VENV)/.installed-dev
	$(BIN)/python -m pytest

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

# pip-audit asks a vulnerability service about every installed package. On a network that
# reaches only a package mirror (this project's CI), PyPI's JSON API answers 404 for each one,
# yet pip-audit says "No known vulnerabilities found", and OSV cannot be reached. So a service
# counts only once it has audited a package; when none has, the audit says so and is skipped.
AUDITED := import json, sys; deps = json.load(sys.stdin)["dependencies"]; \
	sys.exit(not any("skip_reason" not in d for d in deps))

audit: audit-code audit-deps

audit-code: $(VENV)/.installed-dev
	$(BIN)/bandit -q -r app -c pyproject.toml

audit-deps: $(VENV)/.installed-dev
	@for service in pypi osv; do \
		if $(BIN)/pip-audit -s $$service --skip-editable --progress-spinner off -f json \
				2>/dev/null | $(BIN)/python -c '$(AUDITED)' 2>/dev/null; then \
			echo "pip-audit -s $$service --strict --skip-editable"; \
			exec $(BIN)/pip-audit -s $$service --strict --skip-editable --progress-spinner off; \
		fi; \
	done; \
	echo "pip-audit: vulnerability service unreachable (neither PyPI's JSON API nor OSV" \
		"audited a package), skipped"

format: $(VENV)/.installed-dev
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

bench: $(VENV)/.installed-dev
	$(BIN)/python bench/bench_pipeline.py

accuracy: $(VENV)/.installed-dev
	$(BIN)/python bench/accuracy.py

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache *.egg-info
