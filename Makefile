# Two commands do everything on a fresh machine:
#   make run   — build `dronewatt` (no libtorch needed) and replay the demo flight: a
#                simulated M100 delivery from replay/demo.plan, dashboard on :8787
#   make test  — install what the tests need (libtorch, pymavlink venv, Chromium,
#                Mosquitto, nats-server), then every test of the workspace (what CI runs)
SHELL := /bin/bash
CARGO ?= cargo
DEMO_SPEED ?= 10

.PHONY: setup run test lint build build-all bench fuzz clean-setup docs docs-tables
setup:
	@scripts/setup-libtorch.sh
	@scripts/setup-python.sh

# The demo shares `make test`'s build: the same dev profile (dependencies at opt-level 2,
# Cargo.toml) and the same features. `--workspace` unifies features across the workspace as
# `cargo test --workspace` does (`-p dronewatt` alone resolves 9 dependencies, serde among
# them, with other features, so everything above them was built twice); serde's `alloc`
# is named in Cargo.toml because criterion, a dev-dependency, asks for it. After `make
# test`, `make build` prints only 'Finished'. `--bin dronewatt` builds that binary alone:
# it does not link libtorch; `dronewatt-torch` (training, TorchScript models) needs `make
# setup` first.
DW_BUILD = $(CARGO) build --workspace --locked --bin dronewatt
build:
	$(DW_BUILD)

build-all: setup
	$(CARGO) build --locked --workspace

run: build
	./target/debug/dronewatt replay replay/demo.tlog --speed $(DEMO_SPEED) --config config/demo.toml --data-dir off

# After the tests (which build the binary), the book's results tables and the README's
# headline figures are checked against what the commands print now (scripts/docs-tables.py
# --check: writes nothing; skipped with a note where the data set is absent).
test: setup
	@scripts/setup-chromium.sh
	@scripts/setup-tmux.sh
	@scripts/setup-mosquitto.sh
	@scripts/setup-nats.sh
	$(CARGO) test --workspace --locked --no-fail-fast
	@python3 scripts/docs-tables.py --if-available --check

# The code gates CI runs before the tests: rustfmt, clippy with warnings as errors, rustdoc
# with warnings as errors (broken intra-doc links), over the whole workspace (the torch crate
# too, so libtorch first); the links of the book's Markdown and README.md (no build, under a
# second; `make docs` checks the built book); then no import cycle between the top-level
# modules of the product (src/) or the lab (lab/src/) (scripts/module-cycles.py; the crate
# graph itself is acyclic by cargo's rule: lab and torch use the product, never back).
lint: setup
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --workspace --no-deps --locked
	python3 scripts/docs-linkcheck.py --sources
	python3 scripts/arch-files.py --check
	@for d in src lab/src; do printf '%s: ' $$d; python3 scripts/module-cycles.py $$d | tail -1; \
	  python3 scripts/module-cycles.py $$d >/dev/null || exit 1; done

bench: setup
	$(CARGO) bench --workspace --locked

# Fuzz every reader for FUZZ_SECONDS each (cargo fuzz, libFuzzer; see scripts/fuzz.sh).
FUZZ_SECONDS ?= 60
fuzz:
	scripts/fuzz.sh all $(FUZZ_SECONDS)

clean-setup:
	rm -rf .venv-torch .libtorch .venv-py

# The book (docs/, mdBook): mdbook from crates.io into .tools/ (scripts/setup-mdbook.sh, once),
# the results tables refreshed from the commands' --json when the binary is up to date and
# the data set is there (else the committed ones stay), then the build and a link check.
# Output: docs/book/index.html.
docs:
	@scripts/setup-mdbook.sh
	@python3 scripts/docs-tables.py --if-available
	.tools/bin/mdbook build docs
	@python3 scripts/docs-linkcheck.py docs/book

# Rewrite docs/src/generated/*.md from `dronewatt-lab battery-eval --json -` and `plan-eval --json -`
# (needs the data set; builds the lab's binary first). Commit the result.
docs-tables:
	$(CARGO) build --workspace --locked --bin dronewatt-lab
	python3 scripts/docs-tables.py
