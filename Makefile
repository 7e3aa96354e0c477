# Two entry points (see README): `make run` (the main job) and `make test`.
# Both create and reuse the project's own .venv with the pinned dependencies.
PYTHON ?= python3
VENV := .venv
STAMP := $(VENV)/.installed

.PHONY: run test setup clean browser

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet --upgrade pip
	$(VENV)/bin/python -m pip install --quiet -e ".[test]"
	# the spatial reference's numba kernels, compiled once into numba's cache (~20 s of CPU)
	$(VENV)/bin/python -m mechval.reference.spatial.warm
	touch $(STAMP)

setup: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/mechval run

test: $(STAMP) browser
	$(VENV)/bin/python -m pytest

clean:
	rm -rf $(VENV) reports/out

# The report's browser test uses Debian's Chromium. Installing it needs root
# and apt; when that is not possible the test is skipped with the reason.
browser:
	@command -v chromium >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
	      || echo "note: could not install chromium; the browser test will be skipped"; \
	  else echo "note: chromium not installed and cannot be (needs root + apt); the browser test will be skipped"; fi; }
