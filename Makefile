# Two commands (see README): `make test` and `make demo`. Each does ALL the set-up first (scripts/setup_env.sh:
# venv, ROS 2 wheels, interface build, editable install); a second run of the set-up takes about a second.
VENV   ?= $(CURDIR)/.venv
PYTHON := $(VENV)/bin/python
PYTEST_ARGS ?= -q
TESTS ?= test

# DDS discovery stays on this machine (the default range multicasts on every interface).
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export BEARING_ID_VENV := $(VENV)
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: setup test demo clean-venv

setup:
	@bash scripts/setup_env.sh

test: setup
	$(PYTHON) -m pytest $(TESTS) $(PYTEST_ARGS)

demo: setup
	$(PYTHON) -m bearing_id.demo $(DEMO_ARGS)

clean-venv:
	rm -rf $(VENV)
