# Every target creates .venv on first use, so a fresh clone needs nothing but Python 3.11.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
RUN_STAMP := $(VENV)/.installed-run

.PHONY: demo test check bench clean proto certs images

# --no-compile: pip would byte-compile every installed module (15 s on the development
# machine); Python compiles those a run imports, when it imports them (measured on a fresh clone:
# make demo's first stitched frame 64.6 -> 56.0 s after the start).
# The demo installs what the rig runs on (the package and its devices extra); the tests, the
# checks and the benches add their tools to it: a fresh clone's make demo installed in 7.6 s
# instead of 12.5 s.
$(RUN_STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip >/dev/null
	$(PY) -m pip install --no-compile -e '.[devices]'
	touch $(RUN_STAMP)

$(STAMP): $(RUN_STAMP)
	$(PY) -m pip install --no-compile -e '.[test,devices,gis,check]'
	touch $(STAMP)

demo: $(RUN_STAMP)
	$(VENV)/bin/ig demo

test: $(STAMP)
	$(PY) -m pytest

# A test CA and one certificate per service of the rig into $(CERTS) (docs/security.md); existing
# files are kept (ig certs --force replaces them).
RIG ?= deploy/rigs/default.toml
CERTS ?= certs
certs: $(RUN_STAMP)
	$(PY) -c 'import cryptography' 2>/dev/null || $(PY) -m pip install --no-compile -e '.[tls]'
	$(VENV)/bin/ig certs --rig $(RIG) --out $(CERTS)

# Lint (ruff), types (mypy) and the layer contracts of docs/architecture.md (import-linter).
check: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports

# bench_terrain.py builds its 4096^2-voxel terrain on first use (cached, ~40 s, ~5 GB peak).
# bench_visibility.py compares with Mesa's llvmpipe: moderngl comes with the [bench] extra, Mesa's
# EGL and software rasterizer are Debian packages, installed here if missing (as root).
bench: $(STAMP)
	$(PY) -m pip install -e '.[bench]'
	@ldconfig -p | grep -q libEGL_mesa || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && apt-get update -qq && apt-get install -y -qq libegl-mesa0 libgl1-mesa-dri; } \
	  || echo "bench: no Mesa EGL; bench_visibility.py will report llvmpipe as unavailable"
	$(PY) bench/bench_render.py
	$(PY) bench/bench_visibility.py
	$(PY) bench/bench_terrain.py
	$(PY) bench/bench_fog.py
	$(PY) bench/bench_texture.py
	$(PY) bench/bench_frame.py
	$(PY) bench/bench_cigi_queries.py
	$(PY) bench/bench_cigi.py
	$(PY) bench/bench_wire.py
	$(VENV)/bin/ig latency --out bench/results/latency.json

# The docs' views of the bundled world (docs/images/render_views.py): an approach, a low pass,
# the cloud deck; regenerate them after a change to the picture and look at what changed.
images: $(STAMP)
	$(PY) docs/images/render_views.py

# Regenerates the checked-in protobuf/gRPC code; tests/test_proto_generated.py checks it is current.
proto: $(STAMP)
	$(PY) -m grpc_tools.protoc -Iproto --python_out=proto --pyi_out=proto --grpc_python_out=proto proto/ig/v1/*.proto

clean:
	rm -rf $(VENV) out
