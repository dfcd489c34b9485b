//! The cluster examples: docs/BATCH.md shows `scripts/slurm/mpgdrive-array.sbatch` and
//! `scripts/k8s/mpgdrive-indexed-job.yaml` verbatim (one source, no drift), and both split the
//! batch into as many shards as they start tasks.

use std::path::Path;
use yaml_rust2::YamlLoader;

fn read(rel: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
}

/// The number after `prefix` in `text` (up to the first non-digit).
fn number_after(text: &str, prefix: &str) -> usize {
    let at = text
        .find(prefix)
        .unwrap_or_else(|| panic!("no `{prefix}` in {text}"))
        + prefix.len();
    text[at..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect::<String>()
        .parse()
        .unwrap()
}

#[test]
fn the_batch_guide_shows_the_cluster_files_verbatim() {
    let readme = read("docs/BATCH.md");
    let sbatch = read("scripts/slurm/mpgdrive-array.sbatch");
    let job = read("scripts/k8s/mpgdrive-indexed-job.yaml");
    assert!(
        readme.contains(&format!("```sh\n{sbatch}```")),
        "docs/BATCH.md's Slurm block differs from the file"
    );
    assert!(
        readme.contains(&format!("```yaml\n{job}```")),
        "docs/BATCH.md's Kubernetes block differs from the file"
    );
}

#[test]
fn the_slurm_array_runs_one_shard_per_task() {
    let sbatch = read("scripts/slurm/mpgdrive-array.sbatch");
    let tasks = number_after(&sbatch, "--array=1-");
    assert_eq!(number_after(&sbatch, "--shard \"${SLURM_ARRAY_TASK_ID}/"), tasks);
    assert!(sbatch.contains("--out \"results/shard-${SLURM_ARRAY_TASK_ID}\""));
    assert!(
        sbatch.contains("--resume"),
        "a resubmitted task must resume its shard"
    );
    assert!(sbatch.starts_with("#!/bin/bash\n"));
    // sbatch reads #SBATCH lines only before the first command.
    let first_command = sbatch
        .lines()
        .position(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap();
    let directive = sbatch.lines().position(|l| l.starts_with("#SBATCH")).unwrap();
    assert!(directive < first_command);
}

#[test]
fn the_indexed_job_is_a_valid_manifest_with_one_shard_per_index() {
    let docs = YamlLoader::load_from_str(&read("scripts/k8s/mpgdrive-indexed-job.yaml")).unwrap();
    assert_eq!(docs.len(), 1);
    let job = &docs[0];
    assert_eq!(job["apiVersion"].as_str(), Some("batch/v1"));
    assert_eq!(job["kind"].as_str(), Some("Job"));
    assert!(job["metadata"]["name"].as_str().is_some());
    let spec = &job["spec"];
    assert_eq!(spec["completionMode"].as_str(), Some("Indexed"));
    let completions = spec["completions"].as_i64().unwrap() as usize;
    assert_eq!(spec["parallelism"].as_i64(), Some(completions as i64));
    let pod = &spec["template"]["spec"];
    assert_eq!(pod["restartPolicy"].as_str(), Some("Never"));
    let containers = pod["containers"].as_vec().unwrap();
    assert_eq!(containers.len(), 1);
    let c = &containers[0];
    assert_eq!(c["image"].as_str(), Some("mpgdrive:latest"));
    let command: Vec<&str> = c["command"]
        .as_vec()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap())
        .collect();
    assert_eq!(&command[..2], ["sh", "-c"]);
    let line = command[2];
    assert!(line.starts_with("mpgdrive batch "), "{line}");
    assert_eq!(
        number_after(line, "--shard $((JOB_COMPLETION_INDEX + 1))/"),
        completions
    );
    assert!(line.contains("--resume") && line.contains("--out /data/results/shard-$JOB_COMPLETION_INDEX"));
    // The volume the command writes to is mounted, and backed by a claim.
    let mount = &c["volumeMounts"][0];
    assert_eq!(mount["mountPath"].as_str(), Some("/data"));
    let volume = &pod["volumes"][0];
    assert_eq!(volume["name"].as_str(), mount["name"].as_str());
    assert!(volume["persistentVolumeClaim"]["claimName"].as_str().is_some());
}
