# Two entry points, each creating its own virtual environment:
#   make demo   build the FMUs and run the main job
#   make test   run the whole test suite
#   make mutation   mutation testing of the physics and verdict modules (docs/mutation.md);
#                   the report is build/mutation/report.md
#   make test-numeric   the tests whose numbers depend on the BLAS kernel (CI runs them again
#                       with OPENBLAS_CORETYPE=Prescott)
#   make figures        regenerate every figure of docs/ (minutes: the sweeps of the documents)
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-numeric figures build bench mutation clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,plot]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/dronefly build --out build
	$(BIN)/dronefly simulate --out build
	$(BIN)/dronefly demo --out build/cosim

test: $(STAMP)
	$(BIN)/python -m pytest -n 2 -q -rs

test-numeric: $(STAMP)
	$(BIN)/python -m pytest -n 2 -q -rs -m numeric

figures: $(STAMP)
	$(BIN)/python -m dronefly.cli.figures docs

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py
	$(BIN)/python benchmarks/sweep_bench.py

mutation: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[mutation]'
	nice -n 10 $(BIN)/python mutation/run.py $(MODULES)

clean:
	rm -rf $(VENV) build
