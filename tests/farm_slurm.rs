//! A shot on a real Slurm cluster (issue 15): `snell farm slurm --submit` of fox_wading (ripples,
//! so the simulation job matters) in chunks over two compute nodes; every frame bit for bit the
//! frame of a local `snell render` of the whole range; one chunk held and cancelled, so that it
//! never runs, the check job failing and naming its frames; `--submit --resume` then submitting only
//! that chunk; and the check job failing on a deleted frame and naming it.
//!
//! The cluster is the one `SLURM_CONF` points at: `.ci/run` starts one on this machine with
//! `.ci/slurm-cluster start DIR` (munge, slurmctld and two slurmd nodes n1 and n2 over loopback)
//! and stops it afterwards. To run this test alone:
//!
//! ```text
//! export SLURM_CONF=$(.ci/slurm-cluster start /tmp/snell-slurm)
//! cargo test --test farm_slurm
//! .ci/slurm-cluster stop /tmp/snell-slurm
//! ```
//!
//! Without a cluster the test fails saying why; it does not skip. Job state comes from `scontrol
//! show job` (a cluster without slurmdbd has no `sacct`) and from the logs in the output folder.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

const SIZE: &str = "48x27";
const FRAMES: &str = "1-8";
/// Chunks of two frames: array tasks 0-3.
const CHUNK: &str = "2";
/// How long the jobs of one submission may take before the test gives up.
const WAIT: Duration = Duration::from_secs(300);

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// Runs a Slurm client (sinfo, scontrol, scancel, sbatch); must succeed.
fn slurm(tool: &str, args: &[&str]) -> String {
    let output = Command::new(tool)
        .args(args)
        .output()
        .unwrap_or_else(|error| panic!("cannot run {tool} ({error}): is slurm-wlm installed?"));
    assert!(
        output.status.success(),
        "{tool} {args:?} failed: {}",
        text(&output)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Fails (does not skip) unless SLURM_CONF names a running cluster with two idle nodes.
fn require_cluster() {
    let conf = std::env::var_os("SLURM_CONF").unwrap_or_else(|| {
        panic!(
            "no Slurm cluster: SLURM_CONF is not set. This test needs a running cluster; \
             bash .ci/run starts one (export SLURM_CONF=$(.ci/slurm-cluster start DIR))"
        )
    });
    assert!(
        Path::new(&conf).is_file(),
        "no Slurm cluster: SLURM_CONF={} is not a file",
        conf.to_string_lossy()
    );
    let output = Command::new("sinfo")
        .args(["-h", "-N", "-o", "%N %t"])
        .output()
        .unwrap_or_else(|error| panic!("no Slurm cluster: cannot run sinfo ({error})"));
    let nodes = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success() && nodes.lines().filter(|l| l.ends_with(" idle")).count() >= 2,
        "no Slurm cluster with two idle nodes at SLURM_CONF={}: sinfo says {}",
        conf.to_string_lossy(),
        text(&output)
    );
}

fn snell(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("the snell binary runs")
}

/// The three job ids `snell farm slurm --submit` printed, and the array's task list.
struct Submitted {
    simulation: String,
    array: String,
    check: String,
    tasks: String,
}

fn submit(scene: &Path, out: &Path, resume: bool, env: &[(&str, &str)]) -> Submitted {
    let mut args = vec![
        "farm",
        "slurm",
        scene.to_str().unwrap(),
        "--frames",
        FRAMES,
        "--size",
        SIZE,
        "--chunk",
        CHUNK,
        "--out",
        out.to_str().unwrap(),
        "--submit",
    ];
    if resume {
        args.push("--resume");
    }
    let output = snell(&args, env);
    let printed = text(&output);
    assert!(output.status.success(), "farm slurm failed: {printed}");
    let after = |prefix: &str| -> String {
        let line = printed
            .lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no '{prefix}' line in: {printed}"));
        line[prefix.len()..].to_string()
    };
    let array_line = after("chunk array job ");
    let (array, tasks) = array_line.split_once(" (tasks ").unwrap();
    Submitted {
        simulation: after("simulation job "),
        array: array.to_string(),
        check: after("check job "),
        tasks: tasks.trim_end_matches(')').to_string(),
    }
}

/// `JobState` of every job record `scontrol show job ID` lists (an array: one per task), with its
/// array task id (None for a plain job).
fn states(id: &str) -> Vec<(Option<String>, String)> {
    let shown = slurm("scontrol", &["show", "job", "-o", id]);
    shown
        .lines()
        .filter(|line| !line.trim().is_empty())
        .map(|line| {
            let field = |name: &str| {
                line.split_whitespace()
                    .find_map(|word| word.strip_prefix(&format!("{name}=")))
                    .map(str::to_string)
            };
            (field("ArrayTaskId"), field("JobState").unwrap_or_default())
        })
        .collect()
}

fn finished(state: &str) -> bool {
    !matches!(
        state,
        "PENDING" | "RUNNING" | "CONFIGURING" | "COMPLETING" | "SUSPENDED" | "REQUEUED"
    )
}

/// Waits (at most [`WAIT`]) until every job is over; returns each job's records.
fn wait_for(ids: &[&str], out: &Path) -> Vec<Vec<(Option<String>, String)>> {
    let started = Instant::now();
    loop {
        let all: Vec<_> = ids.iter().map(|id| states(id)).collect();
        if all.iter().flatten().all(|(_, state)| finished(state)) {
            return all;
        }
        assert!(
            started.elapsed() < WAIT,
            "the jobs {ids:?} did not finish in {WAIT:?}: {all:?}; squeue: {}; logs: {}",
            slurm("squeue", &[]),
            logs(out)
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

fn log_dir(out: &Path) -> PathBuf {
    out.join("farm/logs")
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|error| panic!("{}: {error}", path.display()))
}

/// Every log, for failure messages.
fn logs(out: &Path) -> String {
    let mut all = String::new();
    for entry in std::fs::read_dir(log_dir(out))
        .into_iter()
        .flatten()
        .flatten()
    {
        all.push_str(&format!(
            "\n--- {}\n{}",
            entry.path().display(),
            std::fs::read_to_string(entry.path()).unwrap_or_default()
        ));
    }
    all
}

fn frame_bytes(out: &Path, frame: u32) -> Vec<u8> {
    let file = out.join(format!("fox_wading.{frame:04}.exr"));
    std::fs::read(&file).unwrap_or_else(|error| panic!("{}: {error}", file.display()))
}

fn only_state(records: &[(Option<String>, String)]) -> &str {
    assert_eq!(records.len(), 1, "{records:?}");
    &records[0].1
}

#[test]
fn a_shot_on_a_slurm_cluster_renders_resumes_and_is_checked() {
    require_cluster();
    let temp = tempfile::tempdir().unwrap();
    let scene = repo("scenes/fox_wading.toml");
    let local = temp.path().join("local");
    let render = common::render_args(&scene, &local, FRAMES, SIZE);
    let output = snell(&render.iter().map(String::as_str).collect::<Vec<_>>(), &[]);
    assert!(output.status.success(), "{}", text(&output));

    // Submitted held (sbatch reads SBATCH_HOLD), so nothing runs before chunk 2 is held and
    // cancelled: deterministic, where cancelling a running task would race.
    let out = temp.path().join("shared");
    let first = submit(&scene, &out, false, &[("SBATCH_HOLD", "1")]);
    assert_eq!(first.tasks, "0,1,2,3");
    let cancelled = format!("{}_2", first.array);
    slurm("scontrol", &["hold", &cancelled]);
    slurm("scancel", &[&cancelled]);
    // Released one by one: releasing the whole array fails on the cancelled task.
    let others: Vec<String> = [0, 1, 3]
        .iter()
        .map(|task| format!("{}_{task}", first.array))
        .collect();
    let mut release = vec!["release", first.simulation.as_str(), first.check.as_str()];
    release.extend(others.iter().map(String::as_str));
    slurm("scontrol", &release);
    let done = wait_for(&[&first.simulation, &first.array, &first.check], &out);
    assert_eq!(only_state(&done[0]), "COMPLETED", "{}", logs(&out));
    let mut tasks: Vec<(String, String)> = done[1]
        .iter()
        .map(|(task, state)| (task.clone().unwrap_or_default(), state.clone()))
        .collect();
    tasks.sort();
    assert_eq!(
        tasks,
        [
            ("0".to_string(), "COMPLETED".to_string()),
            ("1".into(), "COMPLETED".into()),
            ("2".into(), "CANCELLED".into()),
            ("3".into(), "COMPLETED".into()),
        ],
        "{}",
        logs(&out)
    );
    // The check ran after the cancelled task (afterany) and failed naming its frames.
    assert_eq!(only_state(&done[2]), "FAILED", "{}", logs(&out));
    let check = read(&log_dir(&out).join("check.log"));
    assert!(check.contains("2 missing (5-6)"), "{check}");
    assert!(check.contains("--frames 5-6 "), "{check}");

    // The simulation stepped the ripples once; every chunk read its states from checkpoints.
    let simulation = read(&log_dir(&out).join("simulation.log"));
    assert!(simulation.contains("7 frame(s) stepped"), "{simulation}");
    let mut nodes = BTreeSet::new();
    for index in [0, 1, 3] {
        let chunk = read(&log_dir(&out).join(format!("chunk-{index}.log")));
        assert!(
            chunk.contains("ripples: stepped 0 frame(s)"),
            "chunk {index} stepped the simulation itself: {chunk}"
        );
        let node = chunk
            .lines()
            .find_map(|line| {
                line.split_once(" on node ")
                    .map(|(_, node)| node.to_string())
            })
            .unwrap_or_else(|| panic!("chunk {index} names no node: {chunk}"));
        nodes.insert(node);
    }
    assert_eq!(
        nodes,
        BTreeSet::from(["n1".to_string(), "n2".to_string()]),
        "chunks ran over both nodes"
    );
    assert!(
        !log_dir(&out).join("chunk-2.log").exists(),
        "the cancelled chunk never ran"
    );
    let before: Vec<String> = [0, 1, 3]
        .iter()
        .map(|index| read(&log_dir(&out).join(format!("chunk-{index}.log"))))
        .collect();

    // --resume submits only chunk 2, and the check passes.
    let second = submit(&scene, &out, true, &[]);
    assert_eq!(second.tasks, "2", "only the cancelled chunk is resubmitted");
    let done = wait_for(&[&second.simulation, &second.array, &second.check], &out);
    assert_eq!(
        done[1],
        [(Some("2".to_string()), "COMPLETED".to_string())],
        "only task 2 of the resubmitted array ran: {}",
        logs(&out)
    );
    assert_eq!(only_state(&done[2]), "COMPLETED", "{}", logs(&out));
    let simulation = read(&log_dir(&out).join("simulation.log"));
    assert!(
        simulation.contains("0 frame(s) stepped"),
        "the resubmitted simulation found its checkpoints: {simulation}"
    );
    let rerun = read(&log_dir(&out).join("chunk-2.log"));
    assert!(rerun.contains("chunk 2: frames 5-6 on node"), "{rerun}");
    let after: Vec<String> = [0, 1, 3]
        .iter()
        .map(|index| read(&log_dir(&out).join(format!("chunk-{index}.log"))))
        .collect();
    assert_eq!(before, after, "the other chunks did not run again");
    let check = read(&log_dir(&out).join("check.log"));
    assert!(
        check.contains("all 8 frame(s) whole and current"),
        "{check}"
    );

    // Every farm frame is the local frame, bit for bit.
    for frame in 1..=8 {
        assert!(
            frame_bytes(&out, frame) == frame_bytes(&local, frame),
            "frame {frame} from the farm differs from the local render's"
        );
    }

    // A deleted frame: the check job fails and names it.
    std::fs::remove_file(out.join("fox_wading.0003.exr")).unwrap();
    let check_script = out.join("farm/check.sbatch");
    let id = slurm("sbatch", &["--parsable", check_script.to_str().unwrap()]);
    let id = id.trim().split(';').next().unwrap().to_string();
    let done = wait_for(&[&id], &out);
    assert_eq!(only_state(&done[0]), "FAILED", "{}", logs(&out));
    let check = read(&log_dir(&out).join("check.log"));
    assert!(check.contains("1 missing (3)"), "{check}");
    assert!(check.contains("--frames 3 "), "{check}");
}
