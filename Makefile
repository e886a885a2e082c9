# The README's two set-up commands are `make demo` and `make test`; both build .venv themselves.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
TC := $(BIN)/tumblecal
DEMO := $(VENV)/demo

.PHONY: demo test lint bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# installed from pyproject.toml (editable, with the dev extras for tests, lint and types)
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@

demo: $(VENV)/.installed
	@mkdir -p $(DEMO)
	@echo '$$ tumblecal solve --poses sample_data/x.csv sample_data/y.csv sample_data/z.csv -o $(DEMO)/cal.json'
	@$(TC) solve --poses sample_data/x.csv sample_data/y.csv sample_data/z.csv -o $(DEMO)/cal.json
	@echo '$$ tumblecal apply --cal $(DEMO)/cal.json sample_data/capture.csv -o $(DEMO)/corrected.csv'
	@$(TC) apply --cal $(DEMO)/cal.json sample_data/capture.csv -o $(DEMO)/corrected.csv
	@echo '$$ head -3 $(DEMO)/corrected.csv'
	@head -3 $(DEMO)/corrected.csv
	@echo '$$ tumblecal solve --poses sample_data/z.csv'
	@$(TC) solve --poses sample_data/z.csv > $(DEMO)/one-pose.json
	@echo '$$ tumblecal solve --poses sample_data/imucal/xp.csv sample_data/imucal/yp.csv sample_data/imucal/zp.csv --reference 9.81 --input-units counts --units m/s^2 -o $(DEMO)/imucal.yaml'
	@$(TC) solve --poses sample_data/imucal/xp.csv sample_data/imucal/yp.csv sample_data/imucal/zp.csv --reference 9.81 --input-units counts --units m/s^2 -o $(DEMO)/imucal.yaml

test: $(VENV)/.installed
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/pytest -q; status=$$?; [ $$status -eq 0 ] || [ $$status -eq 5 ]

bench: $(VENV)/.installed
	$(BIN)/python tests/bench.py

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
