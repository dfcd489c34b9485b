# `make demo` and `make test` are the two commands a fresh machine needs (see README.md).
# scripts/setup.sh installs what is missing and prints the environment the build needs.
SHELL := /bin/bash
ENV = eval "$$(scripts/setup.sh)"

.PHONY: demo test build bench setup nets clean

setup:
	@$(ENV) && env | grep -E '^(LIBTORCH|SUMO_HOME)='

build:
	@$(ENV) && cargo build --release

demo:
	@$(ENV) && cargo build --release && ./target/release/mpgdrive demo --config configs/paper.toml

# The second clippy builds without the `sumo` feature (no libsumo needed) to keep that build working.
test:
	@$(ENV) && cargo fmt --check && cargo clippy --all-targets -- -D warnings \
		&& cargo clippy --no-default-features --all-targets -- -D warnings && cargo test

# Regenerates sumo_nets/*/*.net.xml from their plain XML sources with netconvert.
nets:
	@$(ENV) && sumo_nets/build.sh

bench:
	@$(ENV) && cargo bench

clean:
	cargo clean
