# `make demo` and `make test` are the two commands a fresh machine needs (see README.md).
# scripts/setup.sh installs what is missing and prints the environment the build needs.
SHELL := /bin/bash
ENV = eval "$$(scripts/setup.sh)"

.PHONY: demo test build bench setup nets clean

setup:
	@$(ENV) && env | grep -E '^(LIBTORCH|SUMO_HOME)='

build:
	@$(ENV) && cargo build --release

# The main job on the bundled policies and network: a short penetration study on the I-80-like
# merge (the game against SUMO's drivers at 0, 30 and 100% controllable vehicles, one seed,
# 5 minutes each), a 5-minute co-sim of the three controllers there (with their time-space
# diagrams), an NGSIM-format replay on a synthetic file (no official data here), then the report
# (Tables II-IV, the specific scenarios, training curves); prints Table II and the report's path.
DEMO = results/demo
demo:
	@$(ENV) && cargo build --release && bin=./target/release/mpgdrive \
		&& $$bin study --shares 0,0.3,1 --seeds 0 --end 300 --out $(DEMO)/study >/dev/null \
		&& $$bin cosim --sumocfg sumo_nets/i80_merge/i80.sumocfg --end 300 --out $(DEMO)/cosim >/dev/null \
		&& $$bin ngsim synth --episodes 200 --out $(DEMO)/synthetic-ngsim.txt \
		&& $$bin ngsim eval --input $(DEMO)/synthetic-ngsim.txt --out $(DEMO)/ngsim >/dev/null \
		&& $$bin report --study $(DEMO)/study --cosim $(DEMO)/cosim --ngsim $(DEMO)/ngsim --out $(DEMO)/report

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
