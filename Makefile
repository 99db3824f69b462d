# The two commands of the README:
#   make demo   run the daemon on the embedded default (replay of real video, no camera)
#   make test   run every test
# Both set up a fresh Debian machine: system packages, .venv, the project editable with its extras,
# and the landmark models (fetched once from PyPI, converted to ONNX). Re-running is fast.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.posed-installed

.PHONY: demo test setup models lint clean

setup: $(STAMP)

$(STAMP): pyproject.toml deploy/bootstrap.sh
	PYTHON=$(PYTHON) VENV=$(VENV) bash deploy/bootstrap.sh
	touch $(STAMP)

models: $(STAMP)
	$(BIN)/posed models fetch

test: models
	bash deploy/check-shared-data.sh
	$(BIN)/python -m pytest

demo: models
	$(BIN)/posed demo

lint: $(STAMP)
	$(BIN)/ruff check daemon hal landmarks fitting falls bench tests

clean:
	rm -rf $(VENV) build *.egg-info
