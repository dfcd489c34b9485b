//! Mutation fuzzing of every parser of user files: the NGSIM loader (both layouts, then the
//! processing), the configuration and merge.toml parsers, the route generator's base file and
//! the SUMO input checks. Each target starts from a corpus (`tests/fuzz_corpus/` and the
//! bundled configuration, geometry and route files), applies random byte and token mutations
//! (flips, deletions, duplications, splices, and numbers replaced by NaN, infinities, zero,
//! negatives and huge values), and fails on any panic, saving the input that caused it.
//!
//! In the test suite each target runs a fixed number of inputs from a fixed seed. A longer run:
//! `MPGDRIVE_FUZZ_SECONDS=600 MPGDRIVE_FUZZ_SEED=7 cargo test --release --test fuzz -- --nocapture`
//! runs each target for that many seconds (the seed and the number of inputs are printed).

use mpgdrive::batch::routes::{DemandSpec, generate};
use mpgdrive::config::Config;
use mpgdrive::ngsim::config::NgsimConfig;
use mpgdrive::sumo::MergeGeometry;
use mpgdrive::sumo::inputs::{check_routes, config_files};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Inputs per target in the test suite.
const CASES: usize = 2000;

/// xorshift64*: a small, seedable generator (the inputs must be reproducible from the seed).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Tokens that break parsers in interesting ways.
const TOKENS: [&str; 16] = [
    "NaN", "nan", "inf", "-inf", "0", "-1", "1e308", "-1e308", "1e-320", "", "\"", "=", ",", "\n", "<", "]",
];

fn is_number_byte(b: u8) -> bool {
    b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'e'
}

/// One to eight random mutations of `input`, with `other` for splices.
fn mutate(rng: &mut Rng, input: &[u8], other: &[u8]) -> Vec<u8> {
    let mut v = input.to_vec();
    for _ in 0..1 + rng.below(8) {
        let len = v.len();
        let at = rng.below(len + 1);
        match rng.below(7) {
            0 if len > 0 => v[at.min(len - 1)] ^= 1 << rng.below(8),
            1 if len > 0 => {
                let end = (at + 1 + rng.below(64)).min(len);
                v.drain(at.min(len - 1)..end);
            }
            2 if len > 0 => {
                let start = at.min(len - 1);
                let end = (start + 1 + rng.below(64)).min(len);
                let chunk = v[start..end].to_vec();
                v.splice(at..at, chunk);
            }
            3 if !other.is_empty() => {
                let start = rng.below(other.len());
                let end = (start + 1 + rng.below(256)).min(other.len());
                v.splice(at..at, other[start..end].iter().copied());
            }
            4 => {
                // A number (the run of number bytes around a position) becomes a token.
                let mut start = at.min(len.saturating_sub(1));
                while start > 0 && is_number_byte(v[start - 1]) {
                    start -= 1;
                }
                let mut end = start;
                while end < len && is_number_byte(v[end]) {
                    end += 1;
                }
                let token = TOKENS[rng.below(TOKENS.len())].as_bytes();
                v.splice(start..end, token.iter().copied());
            }
            5 => {
                let token = TOKENS[rng.below(TOKENS.len())].as_bytes();
                v.splice(at..at, token.iter().copied());
            }
            _ => v.truncate(at),
        }
    }
    v
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn seeds(files: &[&str]) -> Vec<Vec<u8>> {
    files
        .iter()
        .map(|f| std::fs::read(root().join(f)).unwrap())
        .collect()
}

/// Runs `check` on mutated seeds: `CASES` inputs, or `MPGDRIVE_FUZZ_SECONDS` of them. A panic
/// fails the test after saving the input next to the other test outputs.
fn fuzz(target: &str, corpus: &[Vec<u8>], check: impl Fn(&Path)) {
    let seed: u64 = std::env::var("MPGDRIVE_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let budget = std::env::var("MPGDRIVE_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .map(Duration::from_secs_f64);
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("fuzz-{target}"));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("input");
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let started = Instant::now();
    let mut n = 0usize;
    // Quiet the default hook: a caught panic is reported below with its input.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut crash = None;
    while budget.map_or(n < CASES, |b| started.elapsed() < b) {
        let (a, b) = (rng.below(corpus.len()), rng.below(corpus.len()));
        let input = mutate(&mut rng, &corpus[a], &corpus[b]);
        std::fs::write(&file, &input).unwrap();
        if let Err(e) = catch_unwind(AssertUnwindSafe(|| check(&file))) {
            let saved = root()
                .join("target")
                .join(format!("fuzz-crash-{target}-{seed}-{n}"));
            std::fs::write(&saved, &input).unwrap();
            let message = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            crash = Some(format!(
                "{target}: input {n} (seed {seed}) panicked: {message}; saved to {}",
                saved.display()
            ));
            break;
        }
        n += 1;
    }
    std::panic::set_hook(hook);
    let _ = std::fs::remove_dir_all(&dir);
    if let Some(c) = crash {
        panic!("{c}");
    }
    eprintln!(
        "fuzz {target}: {n} inputs in {:.1} s, seed {seed}, no panic",
        started.elapsed().as_secs_f64()
    );
}

fn ngsim_config() -> NgsimConfig {
    NgsimConfig::load(&root().join("configs/ngsim.toml")).unwrap()
}

#[test]
fn fuzz_ngsim_loader_and_processing() {
    let ngsim = ngsim_config();
    let corpus = seeds(&[
        "tests/fuzz_corpus/ngsim/fhwa_text.txt",
        "tests/fuzz_corpus/ngsim/dot_export.csv",
    ]);
    fuzz("ngsim", &corpus, |path| {
        if let Ok(data) = mpgdrive::ngsim::load::load(path, "i-80") {
            let _ = mpgdrive::ngsim::process::prepare(&data, &ngsim);
        }
    });
}

#[test]
fn fuzz_config_parser() {
    let corpus = seeds(&["configs/paper.toml", "configs/smoke.toml"]);
    fuzz("config", &corpus, |path| {
        let _ = Config::load(path);
    });
}

#[test]
fn fuzz_merge_toml_parser() {
    let corpus = seeds(&[
        "sumo_nets/i80_merge/merge.toml",
        "sumo_nets/single_lane_merge/merge.toml",
    ]);
    fuzz("merge", &corpus, |path| {
        let _ = MergeGeometry::load(path);
    });
}

#[test]
fn fuzz_route_generator_base_file() {
    let geometry = MergeGeometry::load(&root().join("sumo_nets/i80_merge/merge.toml")).unwrap();
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-routes-out");
    let spec = DemandSpec {
        scales: vec![0.5],
        ramp_share: None,
        controllable_shares: vec![0.5],
        mainline_share: None,
        seeds: vec![0],
        begin: 0.0,
        duration: 30.0,
        streams: Default::default(),
        loaded: Vec::new(),
    };
    let corpus = seeds(&[
        "sumo_nets/i80_merge/i80.rou.xml",
        "sumo_nets/single_lane_merge/merge.rou.xml",
    ]);
    fuzz("routes", &corpus, |path| {
        let _ = generate(path, std::slice::from_ref(&geometry), &spec, &out);
    });
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn fuzz_sumo_input_checks() {
    let corpus = seeds(&[
        "sumo_nets/i80_merge/i80.sumocfg",
        "sumo_nets/single_lane_merge/merge.sumocfg",
        "sumo_nets/single_lane_merge/merge.rou.xml",
    ]);
    fuzz("sumo-inputs", &corpus, |path| {
        let _ = config_files(path);
        let _ = check_routes(&[path.to_path_buf()], None);
    });
}
