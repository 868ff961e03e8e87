# Two entry points for a fresh machine:  `make demo`  and  `make test`.
# Each creates .venv if missing and installs whatever is missing (Debian packages too).
PY      ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
STAMP   := $(VENV)/.kgarment-installed
DEB     := libsuitesparse-dev libopenblas0-serial chromium chromium-driver
OUT     ?= runs/demo

.PHONY: demo test setup deb bench clean

deb:
	@missing=""; for p in $(DEB); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -q && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -q $$missing; \
	fi

$(VPY):
	$(PY) -m venv $(VENV)

$(STAMP): pyproject.toml | $(VPY)
	$(MAKE) deb
	$(VPY) -m pip install -q --upgrade pip
	# The CPU build of torch first (a bare `torch` requirement would pull a CUDA build).
	$(VPY) -m pip install -q torch==2.13.0
	$(VPY) -m pip install -q -e '.[dev,solver,fabrication,studio,sweep]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/kgarment demo --out $(OUT)

test: $(STAMP)
	$(VPY) -m pytest -q -n auto --dist loadscope --no-loadscope-reorder tests

bench: $(STAMP)
	$(VPY) benchmarks/solver.py

clean:
	rm -rf $(VENV) build src/*.egg-info
