# workzone_ros: `make demo` runs the graph on a generated bag, `make test` runs the suite.
# The virtual environment is created on first use and only reinstalled when setup.py changes.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
DEMO_BAG := bags/demo

.PHONY: all install demo test soak lint bench contact-sheet clean

all: test

$(STAMP): setup.py setup.cfg package.xml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip >/dev/null
	$(BIN)/pip install -q -e '.[wheels,test]'
	$(BIN)/python -m workzone_ros.core.kernels
	touch $(STAMP)

install: $(STAMP)

$(DEMO_BAG)/metadata.yaml: $(STAMP) $(wildcard config/scenarios/demo.yaml)
	$(BIN)/workzone-ros synth --scenario demo --compressed -o $(DEMO_BAG) --overwrite

demo: $(DEMO_BAG)/metadata.yaml
	$(BIN)/workzone-ros launch --bag $(DEMO_BAG) --rate 1.0 --state --score bags/demo_report --report

test: $(STAMP) lint
	$(BIN)/python -m pytest -q test

# minutes of live graph (the reliability campaign: loop, kills, lost sensors, load, 10 min RSS soak);
# `make test` skips them (marker soak); WORKZONE_SOAK_S shortens the soak
soak: $(STAMP) $(DEMO_BAG)/metadata.yaml
	$(BIN)/python -m pytest -q -m soak test/reliability

lint: $(STAMP)
	$(BIN)/ruff check workzone_ros test

bench: $(STAMP)
	$(BIN)/workzone-ros bench all --json bags/bench.json

contact-sheet: $(STAMP)
	$(BIN)/workzone-ros synth sheet -o bags/contact_sheet.png

clean:
	rm -rf $(VENV) build *.egg-info
