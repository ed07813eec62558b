# Two set-up commands: `make repro` and `make test`. Both create .venv when it is missing.
PYTHON ?= python3
VENV ?= .venv
# The CPU wheel of torch lies on this machine kind's disk; a bare `torch` pulls a multi-GB CUDA build.
TORCH_SPEC ?= torch==2.13.0
# where pip finds that wheel (its environment or its configuration), for uv
TORCH_FIND_LINKS ?= $(or $(PIP_FIND_LINKS),$(shell $(PYTHON) -m pip config get global.find-links 2>/dev/null))
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export DVC_NO_ANALYTICS := 1
# Bytecode is compiled on first import and kept (in .venv and src/), not for every package at install: a
# machine that sets PYTHONDONTWRITEBYTECODE would otherwise compile every module again in every process
# (each stage, each test worker), and compiling all of torch, MLflow & co. up front costs more than the
# modules the pipeline imports.  __pycache__/ is in .gitignore and .dvcignore.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: install repro readme test test-fast core-check bench smooth-example params lint clean-venv

$(PY):
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml Makefile | $(PY)
	$(PY) -m pip install --quiet uv
	# uv for torch too (faster than pip), given the folder pip finds the CPU wheel in: uv does not read pip's
	# configuration.  With no such folder, pip as before (uv would take PyPI's CUDA build).
	$(if $(TORCH_FIND_LINKS),$(VENV)/bin/uv pip install --quiet --python $(PY) --find-links $(TORCH_FIND_LINKS),$(PY) -m pip install --quiet) "$(TORCH_SPEC)"
	$(VENV)/bin/uv pip install --quiet --python $(PY) -e ".[dev]"
	# mealpy 3.0.3 pins numpy<=1.26 (lifted upstream, unreleased): install it without its pins; its
	# needs (numpy, scipy, pandas, matplotlib, tqdm) are already there.  Not in pyproject for that reason.
	$(VENV)/bin/uv pip install --quiet --python $(PY) --no-deps "mealpy==3.0.3"
	# OpenVINO (an INT8 runtime the benchmarks compare) keeps its telemetry in its model converters, which
	# we never call: switched off all the same
	$(VENV)/bin/opt_in_out --opt_out > /dev/null
	touch $(STAMP)

install: $(STAMP)

## Compose conf/ into params.yaml (byte-identical to `dvc exp run`), then run the pipeline, timing
## every stage (reports/pipeline_time.json: seconds per stage and per stage family), each stage forked
## from one process that has imported the pipeline's libraries (toolpath.pipeline.warm).
repro: install
	$(PY) -m toolpath.pipeline.config
	PATH="$(abspath $(VENV))/bin:$$PATH" $(PY) -m toolpath.pipeline.warm -- \
		$(PY) -m toolpath.pipeline.stage_times -- $(VENV)/bin/dvc repro
	$(PY) -m toolpath.reports.readme

## Put the measured figures into README.md: the report's summary block (reports/readme_block.md, a DVC output),
## the pipeline's time (reports/pipeline_time.json) and the G-code speeds (reports/bench/gcode.json).
readme: install
	$(PY) -m toolpath.reports.readme

## The whole test suite (unit, config, stage and one end-to-end pipeline test).  Two xdist workers:
## the end-to-end pipeline (mostly one busy core: process start-up) runs beside the rest.
test: install
	$(VENV)/bin/pytest -n 2 --dist loadgroup

test-fast: install
	$(VENV)/bin/pytest -m "not slow"

## The core install alone (no extras) in a fresh venv, then `toolpath smooth` on a corpus program (CI runs it).
core-check:
	bash .ci/core-install

## Benchmarks (speed and memory figures live here, never in tests): writes reports/bench/*.json, then
## re-measures Table 4 (the `benchmark` stage's reports/metrics/inference.json; needs `make repro` first).
bench: install
	$(PY) -m toolpath.bench
	$(PY) -m toolpath.stages.benchmark

## `toolpath smooth` on one real program of ../shared/gcode-corpus: the README's example (reports/smooth/).
SMOOTH_EXAMPLE ?= ../shared/gcode-corpus/tinyg_girl_supercam.gcode
smooth-example: install
	mkdir -p reports/smooth
	$(VENV)/bin/toolpath smooth $(SMOOTH_EXAMPLE) -o reports/smooth/$(notdir $(SMOOTH_EXAMPLE)) --force \
		--report reports/smooth/report.json --plot reports/smooth/before_after.png
	$(VENV)/bin/toolpath smooth $(SMOOTH_EXAMPLE) -o reports/smooth/$(notdir $(SMOOTH_EXAMPLE)) --force \
		--report reports/smooth/report.html

params: install
	$(PY) -m toolpath.pipeline.config

lint: install
	$(VENV)/bin/ruff check src tests

clean-venv:
	rm -rf $(VENV)
