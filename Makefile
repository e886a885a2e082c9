# The README's two set-up commands are `make demo` and `make test`; both build .venv themselves.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
TC := $(BIN)/tumblecal

.PHONY: demo test check fuzz bench same montecarlo docs transcripts clean browser postgres

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# installed from pyproject.toml (editable, with the dev extras for tests, lint and types)
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@

# The README's "Quick start" transcript is this target's output (tests/test_docs.py checks it).
DEMO_COMMANDS := \
	"tumblecal solve --poses sample_data/x.csv sample_data/y.csv sample_data/z.csv --limits sample_data/limits.yaml --serial demo-0001 -o demo/cal.json" \
	"tumblecal apply --cal demo/cal.json sample_data/capture.csv -o demo/corrected.csv" \
	"head -3 demo/corrected.csv" \
	"tumblecal solve --poses sample_data/imucal/xp.csv sample_data/imucal/xn.csv sample_data/imucal/yp.csv sample_data/imucal/yn.csv sample_data/imucal/zp.csv sample_data/imucal/zn.csv --reference 9.81 --units m/s^2 --input-units counts -o demo/imucal.yaml"

demo: $(VENV)/.installed
	@mkdir -p demo
	@export PATH="$(CURDIR)/$(BIN):$$PATH" COLUMNS=80; for cmd in $(DEMO_COMMANDS); do \
		echo "\$$ $$cmd"; $$cmd 2>&1 || exit 1; done

# pytest keeps its rewritten test modules as bytecode even where the environment turns that off
PYTEST := env -u PYTHONDONTWRITEBYTECODE $(BIN)/pytest

# `make test` tries the same Hypothesis examples on every run (the ci profile, tests/conftest.py);
# `make check` random ones (dev), a failing one printed with the blob that replays it
HYPOTHESIS_PROFILE ?= ci

# report --html is tested in a headless Chromium: installed from Debian's packages where it is
# missing and apt-get can (as root); without it that one test is skipped, saying why
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	{ command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ] && \
	  { DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null 2>&1 || \
	    { apt-get update -q >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null 2>&1; }; } || \
	  echo "chromium not installed: the browser test of report --html will be skipped"; }

# Debian's postgresql package, for the records tests on a real server (tests/test_records_postgres.py
# starts its own, on a Unix socket in a temporary folder); skipped with a reason where it cannot be installed
postgres:
	@command -v initdb >/dev/null 2>&1 || ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || \
	{ command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ] && \
	  { DEBIAN_FRONTEND=noninteractive apt-get install -y -q postgresql >/dev/null 2>&1 || \
	    { apt-get update -q >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q postgresql >/dev/null 2>&1; }; } || \
	  echo "postgresql not installed: the records tests on a PostgreSQL server will be skipped"; }

test: $(VENV)/.installed browser postgres
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	HYPOTHESIS_PROFILE=$(HYPOTHESIS_PROFILE) $(PYTEST) -q; status=$$?; [ $$status -eq 0 ] || [ $$status -eq 5 ]

# the fast tier while working: lint, format, types and the tests not marked slow (under 30 s); `make test` runs all
check: $(VENV)/.installed
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(PYTEST) -q -m "not slow"; status=$$?; [ $$status -eq 0 ] || [ $$status -eq 5 ]

# seeded mutation fuzzing of every reader (not part of `make test`): FUZZ_CASES=3000 FUZZ_SEED=1
FUZZ_CASES ?= 3000
FUZZ_SEED ?= 1
fuzz: $(VENV)/.installed
	$(BIN)/python tests/fuzz.py --cases $(FUZZ_CASES) --seed $(FUZZ_SEED) $(if $(FUZZ_ONLY),--only $(FUZZ_ONLY))

# `make bench AGAINST=REV`: each command of this tree against git revision REV's, in turns (a change's cost)
# polars is the baseline `apply`, `segment` and `solve --log` are measured against (the scripts a user
# would write instead): installed into the venv for the benchmark only, like pandas it is no dependency of a command
bench: $(VENV)/.installed
	$(BIN)/python -m pip install --quiet polars
	$(BIN)/python tests/bench.py $(if $(AGAINST),against $(AGAINST))

# `make same AGAINST=REV`: every command of tests/same.py on the real captures, with this tree and with git
# revision REV's package, their exit codes, stderr, stdout and written files compared (a refactor changed no output)
same: $(VENV)/.installed
	$(if $(AGAINST),,$(error make same: give the revision to compare with as AGAINST=REV; e.g. make same AGAINST=HEAD))
	$(BIN)/python tests/same.py $(AGAINST)

# each solver's RMS error over 1000 synthetic captures against its Cramér–Rao bound (docs/accuracy.md)
montecarlo: $(VENV)/.installed
	$(BIN)/python tests/montecarlo.py

# the docs/ pages as a site in site/ (--strict: a broken link or anchor fails; tests/test_docs.py builds it too)
docs: $(VENV)/.installed
	$(BIN)/mkdocs build --strict

# after a change meant to alter what commands print: rerun every console session of README.md and
# docs/ and write the new output into the pages (read the diff: it is what users will see)
transcripts: $(VENV)/.installed
	PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/python tests/transcripts.py --update

clean:
	rm -rf $(VENV) demo site .pytest_cache .mypy_cache .ruff_cache
