# The two commands of the README:
#   make demo   run the daemon on the embedded default (replay of real video, no camera)
#   make test   run every test
# Both set up a fresh Debian machine: system packages, .venv, the project editable with its extras,
# the landmark models (fetched once from PyPI, converted to ONNX) and the numba cache of the fitting kernels
# (`posed warmup`: compiled once, ~30 s; then every process loads them). Re-running is fast.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.posed-installed

.PHONY: demo test setup models warmup lint clean

setup: $(STAMP)

$(STAMP): pyproject.toml deploy/bootstrap.sh
	PYTHON=$(PYTHON) VENV=$(VENV) bash deploy/bootstrap.sh
	touch $(STAMP)

models: $(STAMP)
	$(BIN)/posed models fetch

warmup: $(STAMP)
	$(BIN)/posed warmup

test: models warmup
	bash deploy/check-shared-data.sh
	$(BIN)/python -m pytest

demo: models warmup
	$(BIN)/posed demo

lint: $(STAMP)
	$(BIN)/ruff check posed daemon hal landmarks fitting falls bench camera_model viz client tests deploy

clean:
	rm -rf $(VENV) build dist *.egg-info
