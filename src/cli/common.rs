//! What several commands share: the common arguments, printing to stdout, usage errors and
//! picking the policies of a directory.

use anyhow::{Context as _, Result};
use clap::Args;
use mpgdrive::config::{Config, ScenarioKind};
use mpgdrive::eval::study::{Rules, load_policies};
use mpgdrive::policy::file::Sidecar;
use mpgdrive::policy::{Combine, Mode, PolicyEnsemble, PolicyNet};
use std::path::{Path, PathBuf};

/// Configuration, seed and threads of the commands over the internal simulator.
#[derive(Args)]
pub struct Common {
    /// Configuration file (TOML).
    #[arg(long, default_value = "configs/paper.toml")]
    pub config: PathBuf,
    /// Seed of the initial states (default: the configuration's `seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// [`Common`] validated: the configuration, the seed and the number of threads.
pub struct CommonSettings {
    /// The validated configuration.
    pub config: Config,
    /// `--seed`, or the configuration's.
    pub seed: u64,
    /// Worker threads (at least 1).
    pub threads: usize,
}

impl Common {
    /// Loads the configuration and checks `--threads`.
    pub fn settings(&self) -> Result<CommonSettings> {
        let config = Config::load(&crate::cli::bundled::resolve(&self.config)?)?;
        let seed = self.seed.unwrap_or(config.seed);
        Ok(CommonSettings {
            config,
            seed,
            threads: threads(self.threads)?,
        })
    }
}

/// The two trained policies a comparison needs.
#[derive(Args)]
pub struct PolicyPair {
    /// MARL policy: a file or a directory of one per seed (default: the shipped set of the
    /// configuration's world, policies/mpg or policies/traffic/mpg).
    #[arg(long)]
    pub policy: Option<PathBuf>,
    /// Single-agent policy: a file or a directory of one per seed (default: policies/sarl or
    /// policies/traffic/sarl).
    #[arg(long)]
    pub sarl_policy: Option<PathBuf>,
}

/// Which seeds of a policy directory drive a deployment, and how they act as one.
#[derive(Debug, Clone, Args)]
pub struct SeedChoice {
    /// Which seed's policy drives, from a directory (default: every seed, as one policy; see
    /// --ensemble).
    #[arg(long)]
    pub policy_seed: Option<u64>,
    /// How the seeds of a directory act as one policy: each vehicle's action is the median of
    /// the seeds' actions (the default: one seed that brakes where the others do not leaves it
    /// alone) or their mean.
    #[arg(long, value_enum, default_value_t = Combine::Median)]
    pub ensemble: Combine,
}

impl PolicyPair {
    /// The policy of a mode: as given, else the shipped set of `config`'s world (the bundled
    /// copy when the current directory does not hold it: [`crate::cli::bundled`]).
    pub fn of(&self, mode: Mode, config: &Config) -> Result<PathBuf> {
        let given = match mode {
            Mode::Mpg => &self.policy,
            Mode::Sarl => &self.sarl_policy,
        };
        crate::cli::bundled::resolve(&given.clone().unwrap_or_else(|| shipped_policies(mode, config)))
    }

    /// Both sets (one policy per seed, MARL then single-agent), checked against `config`'s
    /// world rules.
    pub fn load(&self, config: &Config) -> Result<[Vec<(PolicyNet, Sidecar)>; 2]> {
        Ok([
            load_policies(&self.of(Mode::Mpg, config)?, config, Rules::Same)?,
            load_policies(&self.of(Mode::Sarl, config)?, config, Rules::Same)?,
        ])
    }
}

/// The shipped policies of a mode for `config`'s world: `policies/<mode>` for the paper's,
/// `policies/traffic/<mode>` for merge traffic.
pub fn shipped_policies(mode: Mode, config: &Config) -> PathBuf {
    let name = match mode {
        Mode::Mpg => "mpg",
        Mode::Sarl => "sarl",
    };
    match config.scenario.kind {
        ScenarioKind::Paper => Path::new("policies").join(name),
        ScenarioKind::Traffic => Path::new("policies/traffic").join(name),
    }
}

/// `println!` that ends the process quietly when stdout is closed (for example `| head`)
/// instead of panicking on the broken pipe.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout().lock(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            return Err(anyhow::Error::new(e).context("writing to stdout"));
        }
    }};
}
pub(crate) use outln;

/// An error in the user's input, not a failure of the tool (exit code 2).
pub fn usage(message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(mpgdrive::exit::UsageError(message.into()))
}

/// Prints to stdout, ending quietly on a closed pipe.
pub fn print(text: &str) -> Result<()> {
    outln!("{text}");
    Ok(())
}

/// The policies of a file or a directory of seeds, sorted by seed: `seed`'s alone when given.
pub fn select_policies(path: &Path, seed: Option<u64>, config: &Config) -> Result<Vec<(PolicyNet, Sidecar)>> {
    let policies = load_policies(path, config, Rules::Same)?;
    let Some(s) = seed else {
        return Ok(policies);
    };
    let one = policies
        .into_iter()
        .find(|(_, side)| side.seed == s)
        .ok_or_else(|| usage(format!("{}: no policy of seed {s}", path.display())))?;
    Ok(vec![one])
}

/// One policy from a file or a directory of seeds: `seed`, or else the lowest seed.
pub fn pick_policy(path: &Path, seed: Option<u64>, config: &Config) -> Result<PolicyNet> {
    Ok(select_policies(path, seed, config)?.swap_remove(0).0)
}

/// The policy a deployment drives with, and its training seeds: the chosen seed's network of a
/// file or directory, or else every seed as one ensemble.
pub fn deployed_policy(
    path: &Path,
    choice: &SeedChoice,
    config: &Config,
) -> Result<(PolicyEnsemble, Vec<u64>)> {
    let (nets, seeds): (Vec<_>, Vec<_>) = select_policies(path, choice.policy_seed, config)?
        .into_iter()
        .map(|(net, side)| (net, side.seed))
        .unzip();
    let policy = PolicyEnsemble::new(nets, choice.ensemble).with_context(|| format!("{}", path.display()))?;
    Ok((policy, seeds))
}

/// `--threads`: at least 1; all cores when not given.
pub fn threads(given: Option<usize>) -> Result<usize> {
    match given {
        Some(0) => Err(usage("--threads must be at least 1")),
        Some(t) => Ok(t),
        None => Ok(std::thread::available_parallelism().map_or(1, |n| n.get())),
    }
}

/// A progress bar on stderr (hidden when stderr is not a terminal).
pub fn progress_bar(len: u64, template: &str) -> Result<indicatif::ProgressBar> {
    use anyhow::Context as _;
    Ok(indicatif::ProgressBar::new(len)
        .with_style(indicatif::ProgressStyle::with_template(template).context("progress bar template")?))
}
