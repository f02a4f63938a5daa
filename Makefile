# lampfab: `make lamp TARGET=image.png` designs a caustic lamp into build/<NAME>/.
# Targets are files; each stage writes its report last, so a killed stage is redone.
# Phony names: lamp, setup, test, test-fast, clean, bench, help, and one alias per stage
# (make optimize).

TARGET  ?= examples/apple.png
TEXT    ?=
PANORAMA ?=
# Make splits words at spaces: a file name with spaces gives a NAME with underscores.
space  := $(subst ,, )
NAME    ?= $(if $(TEXT),text,$(basename $(notdir $(subst $(space),_,$(or $(PANORAMA),$(TARGET))))))
PROFILE ?= default
FAB     ?= sla_resin
LED     ?= post3535
ALLOW_FAIL ?=
TARGET_FRONT ?=
TARGET_LEFT  ?=
TARGET_RIGHT ?=
TARGET_FLOOR ?=

BUILD  ?= build
B      := $(BUILD)/$(NAME)
VENV   := .venv
PY     := $(VENV)/bin/python
READY  := $(VENV)/.installed
ARGS   = --out "$(B)" --profile "$(PROFILE)" --fab "$(FAB)" --led "$(LED)"
RUN    = $(PY) stages/$(1).py $(ARGS)
TARGETS = --target "$(TARGET)" --target-front "$(TARGET_FRONT)" --target-left "$(TARGET_LEFT)" \
          --target-right "$(TARGET_RIGHT)" --target-floor "$(TARGET_FLOOR)" \
          --text "$(TEXT)" --panorama "$(PANORAMA)"

.DELETE_ON_ERROR:
.PHONY: lamp setup test test-fast clean bench help prepare plan init optimize solid fabcheck export verify FORCE

lamp: $(B)/report.html
	@$(PY) -m lampfab.cli summary $(ARGS)

help:
	@echo "make lamp TARGET=image.png [NAME=..] [PROFILE=draft|quick|default|...] [FAB=sla_resin|acrylic_cnc4|...] [LED=post3535|...]"
	@printf '%s\n' 'make lamp TEXT="Happy birthday"      words instead of an image (build/text/); a typed \n breaks a line'
	@echo "make lamp PANORAMA=examples/panorama.png   a 360° panorama wrapped around the room"
	@echo "make <stage> TARGET=..   one stage and what it needs: prepare plan init optimize solid fabcheck export verify"
	@echo "make test | make test-fast (without the slow tests) | make bench | make clean"
	@echo "variables: TARGET_FRONT/LEFT/RIGHT/FLOOR (per-wall images), ALLOW_FAIL=1 (go on after a failed check),"
	@echo "           BUILD=build (output folder), NAME (default: the image's name)"
	@echo "make setup               the setup alone (system packages, .venv/, lampfab)"
	@echo "without make: .venv/bin/lampfab --help, .venv/bin/lampfab <stage> --help"
	@$(PY) -m lampfab.cli profiles 2>/dev/null \
	  || echo "profiles: profiles/*.toml, profiles/fab/*.toml and profiles/led/*.toml (listed here once the first make has installed lampfab)"

# -- setup: system libraries, virtual environment, Python packages ----------------------
setup: $(READY)

$(READY): pyproject.toml stages/00_setup.sh
	bash stages/00_setup.sh
	python3 -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --upgrade pip
	$(VENV)/bin/pip install --quiet -e '.[test]'
	touch $@

# -- the pipeline ----------------------------------------------------------------------
# Rewritten only when the resolved profiles or the input images change.
$(B)/settings.json: FORCE | $(READY)
	@$(PY) -m lampfab.cli settings $(ARGS) $(TARGETS)

$(B)/prepare.json: $(B)/settings.json
	$(call RUN,10_prepare) $(TARGETS)

# plan designs this image on a coarse grid to measure the LED's blur: it needs the targets.
$(B)/plan.json: $(B)/prepare.json
	$(call RUN,20_plan)

# plan only reports, but a user should read its report before the long stages start.
$(B)/init.json: $(B)/prepare.json | $(B)/plan.json
	$(call RUN,25_init)

$(B)/optimize.json: $(B)/init.json
	$(call RUN,30_optimize)

$(B)/solid.json: $(B)/optimize.json
	$(call RUN,40_solid)

$(B)/checks.json: $(B)/solid.json
	$(call RUN,50_fabcheck) $(if $(ALLOW_FAIL),--allow-fail)

$(B)/export.json: $(B)/checks.json
	$(call RUN,60_export)

$(B)/report.html: $(B)/export.json $(B)/plan.json
	$(call RUN,70_verify)

prepare: $(B)/prepare.json
plan: $(B)/plan.json
init: $(B)/init.json
optimize: $(B)/optimize.json
solid: $(B)/solid.json
fabcheck: $(B)/checks.json
export: $(B)/export.json
verify: $(B)/report.html

# -- development -----------------------------------------------------------------------
test: $(READY)
	$(PY) -m pytest -q

test-fast: $(READY)
	$(PY) -m pytest -q -m "not slow"

bench: $(READY)
	$(PY) bench/bench_methods.py --record

clean:
	rm -rf $(BUILD)

FORCE:
