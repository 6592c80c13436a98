//! A shot on a render farm (issue 15): the Slurm batch scripts of its three jobs, written as plain
//! `#SBATCH` files a TD can read and edit. snell talks to no scheduler itself: it writes these
//! files and calls `sbatch` (see [`cli`]).
//!
//! The three jobs:
//! 1. simulation: `snell farm simulate`, which steps the ripples once over the whole range and
//!    writes the checkpoint of every frame (all the chunks will read) into the output folder;
//! 2. chunks: a job array, one task per chunk of frames, `afterok` on the simulation, each task
//!    `snell render --frames <its chunk>` into the shared folder, its log named after its index;
//! 3. check: `afterany` on the array (so it runs after failures too), `snell farm check`, which
//!    exits non-zero naming every missing or bad frame and the command that re-renders them.

pub mod cli;
pub mod openjd;

use std::path::{Path, PathBuf};

use crate::frame::resume::frame_list;

/// `1-3,7,9-12`: frames as one `--frames` argument.
pub fn frames_arg(frames: &[u32]) -> String {
    frame_list(frames).replace(' ', "")
}

/// Everything the scripts need to know about the shot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Shot {
    /// The `snell` binary the farm nodes run (a path they can all see).
    pub snell: PathBuf,
    pub scene: PathBuf,
    /// The shared output folder (or file pattern) given to every `snell render`.
    pub out: PathBuf,
    /// The folder of the frames, the report, the scripts and the logs.
    pub out_dir: PathBuf,
    pub size: String,
    /// Every frame of the shot, in order.
    pub frames: Vec<u32>,
    /// The frames of each chunk; chunk i is array task i.
    pub chunks: Vec<Vec<u32>>,
    pub partition: Option<String>,
}

/// Splits `frames` into runs of at most `chunk` frames, in order.
pub fn chunk_frames(frames: &[u32], chunk: usize) -> Vec<Vec<u32>> {
    frames.chunks(chunk.max(1)).map(<[u32]>::to_vec).collect()
}

/// `text` as one word for bash: single-quoted unless it is made of plainly safe characters.
pub fn shell_word(text: &str) -> String {
    let safe = !text.is_empty()
        && text
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+%@".contains(c));
    if safe {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

fn path_word(path: &Path) -> String {
    shell_word(&path.to_string_lossy())
}

impl Shot {
    /// The folder the scripts are written to.
    pub fn job_dir(&self) -> PathBuf {
        self.out_dir.join("farm")
    }

    /// The folder of the per-task logs.
    pub fn log_dir(&self) -> PathBuf {
        self.job_dir().join("logs")
    }

    fn header(&self, name: &str, log: &str) -> String {
        let mut text = String::from("#!/bin/bash\n");
        text.push_str(&format!("#SBATCH --job-name={}\n", shell_word(name)));
        text.push_str(&format!(
            "#SBATCH --output={}\n",
            path_word(&self.log_dir().join(log))
        ));
        if let Some(partition) = &self.partition {
            text.push_str(&format!("#SBATCH --partition={}\n", shell_word(partition)));
        }
        text.push_str("#SBATCH --nodes=1\n#SBATCH --ntasks=1\n");
        text
    }

    /// `snell render` of `frames` into the shared folder, as a bash command line.
    pub fn render_command(&self, frames: &str) -> String {
        format!(
            "{} render {} --frames {} --out {} --size {}",
            path_word(&self.snell),
            path_word(&self.scene),
            shell_word(frames),
            path_word(&self.out),
            shell_word(&self.size)
        )
    }

    pub fn name(&self) -> String {
        self.scene
            .file_stem()
            .map_or_else(|| "shot".into(), |s| s.to_string_lossy().into_owned())
    }

    /// `snell farm simulate` of the whole shot into the shared folder, as a bash command line:
    /// steps the ripples once and writes the checkpoint of every frame.
    pub fn simulate_command(&self) -> String {
        format!(
            "{} farm simulate {} --frames {} --out {}",
            path_word(&self.snell),
            path_word(&self.scene),
            shell_word(&frames_arg(&self.frames)),
            path_word(&self.out),
        )
    }

    /// `snell farm check` of the whole shot, as a bash command line.
    pub fn check_command(&self) -> String {
        format!(
            "{} farm check {} --frames {} --out {} --size {}",
            path_word(&self.snell),
            path_word(&self.scene),
            shell_word(&frames_arg(&self.frames)),
            path_word(&self.out),
            shell_word(&self.size)
        )
    }

    /// The simulation job: steps the ripples over the whole range, writing their checkpoints.
    pub fn simulation_script(&self) -> String {
        let mut text = self.header(&format!("{}-sim", self.name()), "simulation.log");
        text.push_str(
            "# Steps the ripple simulation once over the shot and writes the checkpoint of every\n\
             # frame into the output folder; each chunk then reads its states instead of stepping\n\
             # from the first frame.\n\
             set -euo pipefail\n",
        );
        text.push_str(&format!("{}\n", self.simulate_command()));
        text
    }

    /// The chunk job array: task i renders chunk i. Logs are chunk-<index>.log.
    pub fn chunks_script(&self) -> String {
        let mut text = self.header(&format!("{}-chunks", self.name()), "chunk-%a.log");
        text.push_str(&format!(
            "#SBATCH --array=0-{}\n",
            self.chunks.len().saturating_sub(1)
        ));
        text.push_str(
            "# One task per chunk of frames; sbatch --array=LIST on the command line overrides the\n\
             # line above (snell farm slurm --resume submits only the chunks still to render).\n\
             set -euo pipefail\ncase \"$SLURM_ARRAY_TASK_ID\" in\n",
        );
        for (index, chunk) in self.chunks.iter().enumerate() {
            text.push_str(&format!("  {index}) FRAMES={} ;;\n", frames_arg(chunk)));
        }
        text.push_str(
            "  *) echo \"no chunk $SLURM_ARRAY_TASK_ID in this shot\" >&2; exit 2 ;;\nesac\n",
        );
        text.push_str(
            "echo \"chunk $SLURM_ARRAY_TASK_ID: frames $FRAMES on node ${SLURMD_NODENAME:-$(hostname)}\"\n",
        );
        text.push_str(&format!(
            "{} render {} --frames \"$FRAMES\" --out {} --size {}\n",
            path_word(&self.snell),
            path_word(&self.scene),
            path_word(&self.out),
            shell_word(&self.size)
        ));
        text
    }

    /// The check job: every frame whole, current and in the report, or a non-zero exit naming
    /// the others and the command that re-renders them.
    pub fn check_script(&self) -> String {
        let mut text = self.header(&format!("{}-check", self.name()), "check.log");
        text.push_str(
            "# Runs after the chunks, failed or not: checks every frame (EXR whole, made from this\n\
             # scene's inputs, report row present) and names any missing or bad one.\n\
             set -euo pipefail\n",
        );
        text.push_str(&format!("{}\n", self.check_command()));
        text
    }

    /// The indices of the chunks holding any of `frames`.
    pub fn chunks_holding(&self, frames: &[u32]) -> Vec<usize> {
        self.chunks
            .iter()
            .enumerate()
            .filter(|(_, chunk)| chunk.iter().any(|f| frames.contains(f)))
            .map(|(index, _)| index)
            .collect()
    }
}

/// `0,2,5`: array indices as sbatch's --array takes them.
pub fn array_list(indices: &[usize]) -> String {
    indices
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shot() -> Shot {
        let frames: Vec<u32> = (1..=7).collect();
        Shot {
            snell: "/opt/snell/bin/snell".into(),
            scene: "scenes/fox wading.toml".into(),
            out: "/shared/shots/fox".into(),
            out_dir: "/shared/shots/fox".into(),
            size: "160x90".into(),
            chunks: chunk_frames(&frames, 3),
            frames,
            partition: Some("render".into()),
        }
    }

    #[test]
    fn frames_split_into_chunks_in_order() {
        assert_eq!(
            chunk_frames(&[1, 2, 3, 4, 5, 6, 7], 3),
            vec![vec![1, 2, 3], vec![4, 5, 6], vec![7]]
        );
        assert_eq!(chunk_frames(&[5, 9], 0), vec![vec![5], vec![9]]);
    }

    #[test]
    fn chunk_script_maps_each_array_index_to_its_frames() {
        let text = shot().chunks_script();
        assert!(text.starts_with("#!/bin/bash\n"), "{text}");
        assert!(text.contains("#SBATCH --array=0-2\n"), "{text}");
        assert!(text.contains("#SBATCH --partition=render\n"), "{text}");
        assert!(
            text.contains("#SBATCH --output=/shared/shots/fox/farm/logs/chunk-%a.log\n"),
            "{text}"
        );
        assert!(text.contains("  0) FRAMES=1-3 ;;\n"), "{text}");
        assert!(text.contains("  2) FRAMES=7 ;;\n"), "{text}");
        assert!(
            text.contains("render 'scenes/fox wading.toml' --frames \"$FRAMES\""),
            "{text}"
        );
    }

    #[test]
    fn simulation_steps_the_whole_shot_and_check_covers_all() {
        let shot = shot();
        assert!(shot.simulation_script().contains(
            "/opt/snell/bin/snell farm simulate 'scenes/fox wading.toml' --frames 1-7 --out /shared/shots/fox\n"
        ));
        assert!(shot
            .check_script()
            .contains("farm check 'scenes/fox wading.toml' --frames 1-7 --out"));
    }

    #[test]
    fn resumed_chunks_are_those_holding_a_bad_frame() {
        let shot = shot();
        assert_eq!(shot.chunks_holding(&[5]), vec![1]);
        assert_eq!(shot.chunks_holding(&[1, 7]), vec![0, 2]);
        assert_eq!(array_list(&shot.chunks_holding(&[1, 7])), "0,2");
    }

    #[test]
    fn shell_words_quote_what_bash_would_split() {
        assert_eq!(shell_word("a/b.toml"), "a/b.toml");
        assert_eq!(shell_word("a b"), "'a b'");
        assert_eq!(shell_word("it's"), r"'it'\''s'");
        assert_eq!(shell_word(""), "''");
    }
}
