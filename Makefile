# Two commands do everything on a fresh machine:
#   make run   — install what is missing (libtorch, test venv), build, replay the demo flight
#   make test  — the same set-up, then every test (what CI runs)
SHELL := /bin/bash
CARGO ?= cargo
DEMO_SPEED ?= 10

.PHONY: setup run test build bench fuzz clean-setup
setup:
	@scripts/setup-libtorch.sh
	@scripts/setup-python.sh

# The dev profile builds dependencies at opt-level 2 (Cargo.toml), so the demo shares
# `make test`'s build instead of compiling libtorch bindings and MAVLink twice.
build: setup
	$(CARGO) build --locked

run: build
	./target/debug/dronewatt replay replay/demo.tlog --speed $(DEMO_SPEED) --config config/demo.toml

test: setup
	@scripts/setup-chromium.sh
	@scripts/setup-mosquitto.sh
	$(CARGO) test --locked --no-fail-fast

bench: setup
	$(CARGO) bench --locked

# Fuzz every reader for FUZZ_SECONDS each (cargo fuzz, libFuzzer; see scripts/fuzz.sh).
FUZZ_SECONDS ?= 60
fuzz: setup
	scripts/fuzz.sh all $(FUZZ_SECONDS)

clean-setup:
	rm -rf .venv-torch .libtorch .venv-py
