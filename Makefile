# The README's two set-up commands: `make run` and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
HOST ?= 127.0.0.1
PORT ?= 8000

# One install at a time: `make -j test` would otherwise run two pip installs into the venv.
.NOTPARALLEL:

.PHONY: run test lint audit audit-code audit-deps format typecheck bench accuracy scenes clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed-run: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@ $(VENV)/.installed-run

# The detection kernels, compiled into Numba's cache beside the code (about ten seconds,
# again whenever their code changes): otherwise the first camera activated after a start
# waits for them, and its first alarm comes seconds late.
KERNEL_SOURCES := app/vision/compiled.py app/vision/noise.py app/vision/preprocess.py \
	$(wildcard app/vision/motion/adaptive/*.py)

$(VENV)/.kernels: $(VENV)/.installed-run $(KERNEL_SOURCES)
	$(BIN)/python -P -c "from app.vision.pipeline import warm_up; warm_up()"
	touch $@

run: $(VENV)/.kernels
	$(BIN)/vigil serve --host $(HOST) --port $(PORT)

# Tests that measure a rate on the whole machine run first, in a pytest of their own:
# after the 17 minutes of the others they read about half, in the same process or in a
# fresh one, with nothing else running (tests/api/test_api_browser_live.py).
test: $(VENV)/.installed-dev $(VENV)/.kernels
	$(BIN)/python -m pytest -m own_process; first=$$?; \
	$(BIN)/python -m pytest -m "not own_process"; second=$$?; \
	[ $$first -eq 0 ] && [ $$second -eq 0 ]

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

# pip-audit asks a vulnerability service about every installed package. On a network that
# reaches only a package mirror (this project's CI), PyPI's JSON API answers 404 for each one,
# yet pip-audit says "No known vulnerabilities found", and OSV cannot be reached. So each
# service runs once, its JSON read by AUDIT_REPORT: it counts only once it has audited a
# package (exit 2: try the next; with none, the audit says so and is skipped). Then a known
# vulnerability fails the audit, and so does a package it could not audit, as --strict
# would (which cannot be used: it refuses the editable Vigil that --skip-editable skips).
define AUDIT_REPORT
import json, sys
service = sys.argv[1]
try:
    deps = json.load(sys.stdin)["dependencies"]
except (ValueError, KeyError, TypeError):
    sys.exit(2)
audited = [d for d in deps if "skip_reason" not in d]
if not audited:
    sys.exit(2)
EDITABLE = "distribution marked as editable"
unaudited = [d for d in deps if "skip_reason" in d and d["skip_reason"] != EDITABLE]
vulns = [(d, v) for d in audited for v in d["vulns"]]
for d, v in vulns:
    fix = ", ".join(v["fix_versions"]) or "none yet"
    print(f"{d['name']} {d['version']}: {v['id']} (fixed in: {fix})")
for d in unaudited:
    print(f"{d['name']}: not audited: {d['skip_reason']}")
print(
    f"pip-audit -s {service}: {len(audited)} packages audited, {len(vulns)} known "
    f"vulnerabilities, {len(unaudited)} packages not audited"
)
sys.exit(1 if vulns or unaudited else 0)
endef
export AUDIT_REPORT

audit: audit-code audit-deps

audit-code: $(VENV)/.installed-dev
	$(BIN)/bandit -q -r app -c pyproject.toml

audit-deps: $(VENV)/.installed-dev
	@for service in pypi osv; do \
		$(BIN)/pip-audit -s $$service --skip-editable --progress-spinner off -f json \
			2>/dev/null | $(BIN)/python -c "$$AUDIT_REPORT" $$service; \
		status=$$?; \
		if [ $$status -ne 2 ]; then exit $$status; fi; \
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

# The scene sweep against its checked-in baseline (bench/scenes_baseline.json).
scenes: $(VENV)/.installed-dev $(VENV)/.kernels
	$(BIN)/python bench/scenes.py --jobs 2

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache *.egg-info
