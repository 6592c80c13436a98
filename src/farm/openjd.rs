//! The shot as an Open Job Description job template (specification `jobtemplate-2023-09`, the
//! format behind AWS Deadline Cloud): the same three jobs as the Slurm scripts, as three steps.
//!
//! - `Simulate`: `snell farm simulate`, the ripples stepped once, every frame's checkpoint written;
//! - `Render`, depending on `Simulate`: one task per chunk, the chunk's frames the task parameter
//!   `Frames` (a STRING such as `1-4`, exactly the `--frames` of the chunk, so the chunks are those
//!   of the Slurm array, gaps in the frame list included);
//! - `Check`, depending on `Render`: `snell farm check` of every frame.
//!
//! OpenJD runs a step only when every step it depends on succeeded (there is no `afterany`): after a
//! failed task, run `snell farm check` yourself (or the Check step alone with
//! `openjd run --step Check --no-run-dependencies`) to have the missing frames named.
//!
//! Commands are argument lists, not shell lines: no quoting, any path works.

use serde_json::{json, Value};

use super::{frames_arg, Shot};

/// The specification version the template is written in.
pub const SPECIFICATION: &str = "jobtemplate-2023-09";

fn action(shot: &Shot, args: Vec<String>) -> Value {
    json!({
        "actions": {
            "onRun": {
                "command": shot.snell.to_string_lossy(),
                "args": args,
            }
        }
    })
}

fn path(p: &std::path::Path) -> String {
    p.to_string_lossy().into_owned()
}

impl Shot {
    /// `snell render SCENE --frames FRAMES --out OUT --size WxH` as an argument list.
    fn render_args(&self, frames: &str) -> Vec<String> {
        vec![
            "render".into(),
            path(&self.scene),
            "--frames".into(),
            frames.into(),
            "--out".into(),
            path(&self.out),
            "--size".into(),
            self.size.clone(),
        ]
    }

    /// The job template: three steps, `Render` depending on `Simulate` and `Check` on `Render`,
    /// the chunks as the values of `Render`'s task parameter `Frames`.
    pub fn openjd_template(&self) -> Value {
        let all = frames_arg(&self.frames);
        let chunks: Vec<String> = self.chunks.iter().map(|c| frames_arg(c)).collect();
        let simulate = vec![
            "farm".into(),
            "simulate".into(),
            path(&self.scene),
            "--frames".into(),
            all.clone(),
            "--out".into(),
            path(&self.out),
        ];
        let mut check = self.render_args(&all);
        check[0] = "check".into();
        check.insert(0, "farm".into());
        json!({
            "specificationVersion": SPECIFICATION,
            "name": format!("snell {}", self.name()),
            "description": format!(
                "Written by snell farm openjd: {} frame(s) of {} at {} in {} chunk(s) into {}",
                self.frames.len(),
                path(&self.scene),
                self.size,
                self.chunks.len(),
                path(&self.out)
            ),
            "steps": [
                {
                    "name": "Simulate",
                    "description": "Steps the ripples once over the shot and writes every frame's checkpoint into the output folder.",
                    "script": action(self, simulate),
                },
                {
                    "name": "Render",
                    "description": "One task per chunk: snell render of the chunk's frames into the shared output folder.",
                    "dependencies": [{ "dependsOn": "Simulate" }],
                    "parameterSpace": {
                        "taskParameterDefinitions": [
                            { "name": "Frames", "type": "STRING", "range": chunks }
                        ]
                    },
                    "script": action(self, self.render_args("{{Task.Param.Frames}}")),
                },
                {
                    "name": "Check",
                    "description": "Checks every frame (EXR whole, made from this scene's inputs, report row present); fails naming the missing or bad ones.",
                    "dependencies": [{ "dependsOn": "Render" }],
                    "script": action(self, check),
                }
            ]
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::chunk_frames;
    use super::*;

    #[test]
    fn three_steps_with_the_chunks_as_the_task_parameter() {
        let frames = vec![1, 2, 3, 4, 5, 9, 10];
        let shot = Shot {
            snell: "/opt/snell".into(),
            scene: "/s/fox wading.toml".into(),
            out: "/shared/fox".into(),
            out_dir: "/shared/fox".into(),
            size: "160x90".into(),
            chunks: chunk_frames(&frames, 3),
            frames,
            partition: None,
        };
        let template = shot.openjd_template();
        assert_eq!(template["specificationVersion"], "jobtemplate-2023-09");
        let steps = template["steps"].as_array().unwrap();
        let names: Vec<&str> = steps.iter().map(|s| s["name"].as_str().unwrap()).collect();
        assert_eq!(names, ["Simulate", "Render", "Check"]);
        assert_eq!(steps[1]["dependencies"][0]["dependsOn"], "Simulate");
        assert_eq!(steps[2]["dependencies"][0]["dependsOn"], "Render");
        let parameter = &steps[1]["parameterSpace"]["taskParameterDefinitions"][0];
        assert_eq!(parameter["range"], json!(["1-3", "4-5,9", "10"]));
        let run = &steps[1]["script"]["actions"]["onRun"];
        assert_eq!(run["command"], "/opt/snell");
        assert_eq!(
            run["args"],
            json!([
                "render",
                "/s/fox wading.toml",
                "--frames",
                "{{Task.Param.Frames}}",
                "--out",
                "/shared/fox",
                "--size",
                "160x90"
            ])
        );
        let check = &steps[2]["script"]["actions"]["onRun"]["args"];
        assert_eq!(check[0], "farm");
        assert_eq!(check[1], "check");
        assert_eq!(check[4], "1-5,9-10");
        let simulate = &steps[0]["script"]["actions"]["onRun"]["args"];
        assert_eq!(simulate[1], "simulate");
    }
}
