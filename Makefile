# Two commands do everything on a fresh machine:
#   make run   — install what is missing (libtorch, test venv), build, replay the demo flight
#   make test  — the same set-up, then every test (what CI runs)
SHELL := /bin/bash
CARGO ?= cargo
DEMO_SPEED ?= 10

.PHONY: setup run test build bench clean-setup
setup:
	@scripts/setup-libtorch.sh
	@scripts/setup-python.sh

build: setup
	$(CARGO) build --release --locked

run: build
	./target/release/dronewatt replay replay/demo.tlog --speed $(DEMO_SPEED) --config config/demo.toml

test: setup
	@scripts/setup-chromium.sh
	$(CARGO) test --locked --no-fail-fast

bench: setup
	$(CARGO) bench --locked

clean-setup:
	rm -rf .venv-torch .libtorch .venv-py
