# tempcomp: `make demo` runs the main job on the virtual board, `make test` runs every test.
# Both set up what they need first (`make setup`): a .venv from requirements.txt and the
# node tools (MicroPython WebAssembly VM, pyright) from tools/package-lock.json, and the real
# interpreters in build/fw (Cortex-M3/M7 MicroPython firmware, CircuitPython, mpy-cross; see
# tools/firmware/build.py), built from MICROPY_SRC= / CIRCUITPY_SRC= or ../shared/vendor.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
NODE_MODULES := tools/node_modules
PORT ?=
BOARD ?= virtual
BOARD_TCP ?= 2323
VBOARD := $(PY) -m tools board
PYTEST_ARGS ?=
# make test runs the suite in this many pytest-xdist workers, a test file per worker at a time (its
# module fixtures stay in one process); the machines it must finish on in 10 minutes have 2 cores
TEST_JOBS ?= 2
MICROPY_SRC ?=
CIRCUITPY_SRC ?=

.PHONY: setup fw test demo bench mpy typecheck lint deploy dist clean board board-start board-stop gap gap-check

setup: $(VENV)/.stamp $(NODE_MODULES)/.stamp fw

# builds only what is missing from build/fw (delete a file there to rebuild it)
fw: $(VENV)/.stamp
	$(PY) -m tools.firmware.build $(if $(MICROPY_SRC),--micropython-src "$(MICROPY_SRC)") $(if $(CIRCUITPY_SRC),--circuitpython-src "$(CIRCUITPY_SRC)")

$(VENV)/.stamp: requirements.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	touch $@

$(NODE_MODULES)/.stamp: tools/package.json tools/package-lock.json
	cd tools && npm ci --no-audit --no-fund --loglevel=error
	touch $@

test: setup typecheck
	$(PY) -m ruff check lib boards tools host_tests
	$(PY) -m pytest -q -n $(TEST_JOBS) --dist loadfile $(PYTEST_ARGS)

typecheck: setup
	$(NODE_MODULES)/.bin/pyright -p pyrightconfig.json

lint: setup
	$(PY) -m ruff check lib boards tools host_tests

# The main job: virtual board, deploy, scripted calibration session, resets, sweep, plot, gap
# diagnosis of a real log. BOARD=pico: the same on the virtual Raspberry Pi Pico (the real RP2040
# firmware, tools/pico). PORT=/dev/ttyACM0 BOARD=pico runs it against a real board.
demo: setup
	PORT="$(PORT)" BOARD="$(if $(PORT),$(BOARD),$(if $(filter pico,$(BOARD)),pico,virtual))" DEMO_TCP=$(if $(filter command line environment,$(origin BOARD_TCP)),$(BOARD_TCP),0) $(PY) -m tools demo

bench: setup
	$(PY) -m tools bench

# Sim-to-real gap diagnosis of a log (see README): make gap LOG=train.csv [WITHHELD=held.csv]
# [EXPORT=out/model.json: the augmented model for the board, docs/augment.md]
gap: setup
	@test -n "$(LOG)" || { echo "usage: make gap LOG=train.csv [WITHHELD=held.csv] [EXPORT=out/model.json]"; exit 2; }
	@mkdir -p out
	$(PY) -m tools gap $(LOG) $(if $(WITHHELD),--withheld $(WITHHELD)) --json out/gap.json --plot out/gap.png $(if $(EXPORT),--export $(EXPORT))

# The blind benchmark of the gap diagnosis: 27 generated cases with hidden labels;
# SET=wander the random-walk set of tools/gapbench/wander.py (20 seeds), SET=both the two in turn
gap-check: setup
	$(PY) -m tools gap-check $(if $(SET),--set $(SET))

mpy: setup
	$(PY) -m tools mpy build/mpy

# .mpy files by default (PY_SOURCES=1: the .py sources); docs/install.md
deploy: setup
	BOARD_TCP=$(BOARD_TCP) $(PY) -m tools deploy --port "$(PORT)" --board "$(BOARD)" $(if $(filter 1 yes,$(PY_SOURCES)),--py)

# mip-installable .mpy packages, one per .mpy version: dist/mpy-v6.3/package.json + tempcomp/*.mpy
dist: setup
	$(PY) -m tools dist dist

# The virtual board: the MicroPython VM serving its REPL on a pty (build/vboard/tty, for
# `mpremote connect build/vboard/tty repl`) and on 127.0.0.1:$(BOARD_TCP) (exec, cp, mount), flash kept
# in build/vboard/flash/. `make board` runs it in the foreground; board-start/board-stop in the background.
# BOARD=pico: the virtual Raspberry Pi Pico instead (the real RP2040 firmware on an emulated RP2040,
# tools/pico), on the same front end; its flash is the littlefs image build/pico/flash.img.
BOARD_ARG = $(if $(filter pico,$(BOARD)),--board pico)

board: setup
	$(VBOARD) --port $(BOARD_TCP) $(BOARD_ARG)

board-start: setup
	$(VBOARD) --port $(BOARD_TCP) --detach $(BOARD_ARG)

board-stop:
	node tools/vboard/server.mjs --stop $(BOARD_ARG)

clean:
	rm -rf build dist $(VENV) $(NODE_MODULES)
