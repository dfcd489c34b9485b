# `make demo` and `make test` are the two commands a fresh machine needs (see README.md).
# scripts/setup.sh installs what is missing and prints the environment the build needs.
SHELL := /bin/bash
ENV = eval "$$(scripts/setup.sh)"

.PHONY: demo test build bench setup net clean

setup:
	@$(ENV) && env | grep -E '^(LIBTORCH|SUMO_HOME)='

build:
	@$(ENV) && cargo build --release

demo:
	@$(ENV) && cargo build --release && ./target/release/mpgdrive demo --config configs/paper.toml

test:
	@$(ENV) && cargo fmt --check && cargo clippy --all-targets -- -D warnings && cargo test

bench:
	@$(ENV) && cargo bench

clean:
	cargo clean
