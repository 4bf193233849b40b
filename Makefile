# Two commands (see README): `make test` and `make demo`. Each does ALL the set-up first (scripts/setup_env.sh:
# venv, ROS 2 wheels, interface build, editable install); a second run of the set-up takes about a second.
VENV   ?= $(CURDIR)/.venv
PYTHON := $(VENV)/bin/python
PYTEST_ARGS ?= -q
# the suite on every core (pytest-xdist; one test file per worker, so a module's fixtures are built once)
PYTEST_PARALLEL ?= -n auto --dist loadfile
TESTS ?= test

# DDS stays on this machine: LOCALHOST discovery, and the Fast DDS profile params/fastdds_localhost.xml, which binds
# every socket that receives DDS traffic to 127.0.0.1 (UDPv4 on 127.0.0.1 + shared memory, no multicast);
# test/test_stock_tools.py checks a node's sockets.  Another profile: `make demo DDS_PROFILE=/path/to/profile.xml`.
DDS_PROFILE ?= $(CURDIR)/params/fastdds_localhost.xml
export FASTRTPS_DEFAULT_PROFILES_FILE := $(DDS_PROFILE)
export FASTDDS_DEFAULT_PROFILES_FILE := $(DDS_PROFILE)
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export BEARING_ID_VENV := $(VENV)
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: setup test demo clean-venv

setup:
	@bash scripts/setup_env.sh

test: setup
	$(PYTHON) -m pytest $(TESTS) $(PYTEST_PARALLEL) $(PYTEST_ARGS)

demo: setup
	$(PYTHON) -m bearing_id.demo $(DEMO_ARGS)

clean-venv:
	rm -rf $(VENV)
