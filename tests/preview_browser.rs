//! `snell preview` in a real browser: headless Chromium driven through WebDriver (Debian's
//! `chromium` and `chromium-driver`; `bash .ci/run` installs them). The page loads, a dragged
//! slider shows the frame it lands on — the same pixels as `snell render --png` of that frame at
//! the same size —, the flag strip has one entry per frame, and a broken edit of the scene file
//! shows the error (file and line) on the page until a fixed one recovers.
//!
//! Without chromium and chromedriver this test FAILS with a message saying how to install them:
//! a browser test that skips itself checks nothing.

use std::io::{BufRead, BufReader};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::json;

const SIZE: &str = "640x360";
const CHROMIUM: &str = "/usr/bin/chromium";
const CHROMEDRIVER: &str = "/usr/bin/chromedriver";

/// A child process killed when the test ends, however it ends.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn snell() -> Command {
    Command::new(env!("CARGO_BIN_EXE_snell"))
}

/// Starts `snell preview` on a free port; returns the process and the page's address (the
/// first line the preview prints).
fn start_preview(scene: &Path, out: &Path) -> (Running, String) {
    let mut child = snell()
        .arg("preview")
        .arg(scene)
        .args(["--port", "0", "--size", SIZE, "--out"])
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("snell preview starts");
    let stdout = child.stdout.take().expect("piped stdout");
    let running = Running(child);
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("the preview prints its address");
    let url = line
        .trim()
        .rsplit_once(" on ")
        .map(|(_, url)| url.to_string())
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"));
    (running, url)
}

fn start_chromedriver() -> (Running, String) {
    for program in [CHROMIUM, CHROMEDRIVER] {
        assert!(
            Path::new(program).exists(),
            "{program} is missing: install Debian's chromium and chromium-driver \
             (apt-get install chromium chromium-driver; `bash .ci/run` does this)"
        );
    }
    let port = TcpListener::bind("127.0.0.1:0")
        .and_then(|listener| listener.local_addr())
        .expect("a free port")
        .port();
    let child = Command::new(CHROMEDRIVER)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromedriver starts");
    let deadline = Instant::now() + Duration::from_secs(20);
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            Instant::now() < deadline,
            "chromedriver did not listen within 20 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    (Running(child), format!("http://127.0.0.1:{port}"))
}

async fn connect(driver_url: &str) -> Client {
    // As root without a display: no sandbox, no GPU, and no background network traffic (the
    // machine's closed network refuses it, which slows Chromium down).
    let capabilities = json!({
        "goog:chromeOptions": {
            "binary": CHROMIUM,
            "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", "--window-size=1100,900", "--force-color-profile=srgb"
            ]
        }
    });
    let serde_json::Value::Object(capabilities) = capabilities else {
        unreachable!()
    };
    ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
        .capabilities(capabilities)
        .connect(driver_url)
        .await
        .expect("a WebDriver session in headless Chromium")
}

/// Evaluates `script` (a function body returning a value) until `accept` takes its result.
async fn wait_for(
    client: &Client,
    what: &str,
    script: &str,
    accept: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let value = client.execute(script, vec![]).await.expect("script runs");
        if accept(&value) {
            return value;
        }
        assert!(
            Instant::now() < deadline,
            "timed out waiting for {what}; last value {value}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

const SHOWN_FRAME: &str = "const img = document.getElementById('frame'); \
    const stale = document.getElementById('viewport').classList.contains('stale'); \
    return stale || !img.complete ? null : { frame: img.dataset.frame, generation: img.dataset.generation };";

/// The pixels the page shows, read back through a canvas at the image's own size.
async fn shown_pixels(client: &Client) -> image::RgbaImage {
    let data_url = client
        .execute(
            "const img = document.getElementById('frame'); \
             const canvas = document.createElement('canvas'); \
             canvas.width = img.naturalWidth; canvas.height = img.naturalHeight; \
             canvas.getContext('2d').drawImage(img, 0, 0); \
             return canvas.toDataURL('image/png');",
            vec![],
        )
        .await
        .expect("canvas readback");
    let encoded = data_url
        .as_str()
        .and_then(|url| url.strip_prefix("data:image/png;base64,"))
        .expect("a PNG data URL");
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(encoded)
        .expect("base64");
    image::load_from_memory(&bytes).expect("a PNG").to_rgba8()
}

/// `snell render --png` of one frame at the preview size: the tone-mapped image the page should show.
fn cli_render(scene: &Path, frame: u32, out: &Path) -> image::RgbaImage {
    let status = snell()
        .arg("render")
        .arg(scene)
        .args([
            "--frames",
            &frame.to_string(),
            "--size",
            SIZE,
            "--png",
            "--out",
        ])
        .arg(out)
        .status()
        .expect("snell render runs");
    assert!(status.success());
    image::open(out.join(format!("pool.{frame:04}.png")))
        .expect("the render's PNG")
        .to_rgba8()
}

fn max_channel_difference(a: &image::RgbaImage, b: &image::RgbaImage) -> u8 {
    assert_eq!(a.dimensions(), b.dimensions());
    a.as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn preview_page_in_headless_chromium() {
    let temp = tempfile::tempdir().unwrap();
    let scene: PathBuf = temp.path().join("pool.toml");
    let original =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pool.toml"))
            .unwrap();
    save(&scene, &original);
    let (_preview, url) = start_preview(&scene, &temp.path().join("out"));
    let (_driver, driver_url) = start_chromedriver();
    let client = connect(&driver_url).await;
    client.goto(&url).await.expect("the page loads");

    // The page opens on the first frame.
    let shown = wait_for(&client, "the first frame", SHOWN_FRAME, |v| !v.is_null()).await;
    assert_eq!(shown["frame"], "1");
    let first_frame_pixels = shown_pixels(&client).await;

    // One strip entry per frame (pool.toml: frames 1-48), all counted eventually.
    let entries = wait_for(
        &client,
        "the strip's counts",
        "const entries = document.querySelectorAll('#strip .entry'); \
         return document.querySelectorAll('#strip .entry.pending').length === 0 ? entries.length : null;",
        |v| !v.is_null(),
    )
    .await;
    assert_eq!(entries, 48, "one strip entry per frame");
    let titles = client
        .execute(
            "return [...document.querySelectorAll('#strip .entry')].map(e => e.title);",
            vec![],
        )
        .await
        .unwrap();
    assert!(
        titles[23].as_str().unwrap().starts_with("frame 24 "),
        "strip entries are in frame order: {}",
        titles[23]
    );

    // Drag the slider's thumb from the left end to about 60 % of its length.
    let slider = client.find(Locator::Css("#slider")).await.unwrap();
    let (_, _, width, _) = slider.rectangle().await.unwrap();
    let drag = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: slider.clone(),
            duration: None,
            x: -width / 2.0 + 6.0,
            y: 0.0,
        })
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(PointerAction::MoveBy {
            duration: Some(Duration::from_millis(400)),
            x: width * 0.6,
            y: 0.0,
        })
        .then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
    client.perform_actions(drag).await.expect("the drag runs");
    let value = client
        .execute("return document.getElementById('slider').value;", vec![])
        .await
        .unwrap();
    let frame: u32 = value.as_str().unwrap().parse().unwrap();
    assert!(
        (20..=40).contains(&frame),
        "the drag should land near 60 % of the timeline, got frame {frame}"
    );
    // The page reports the frame as a string; comparing the JSON value with the bare number would
    // never match, so compare against the text.
    let frame_text = frame.to_string();
    let shown = wait_for(&client, "the dragged-to frame", SHOWN_FRAME, |v| {
        v["frame"] == frame_text
    })
    .await;
    let label = client
        .find(Locator::Css("#frame-label"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        label.contains(&format!("frame {frame} / 48")),
        "label {label:?}"
    );
    let page_pixels = shown_pixels(&client).await;
    let cli_pixels = cli_render(&scene, frame, &temp.path().join("cli"));
    let difference = max_channel_difference(&page_pixels, &cli_pixels);
    assert_eq!(
        difference, 0,
        "the page's frame {frame} differs from `snell render --png` of it by up to {difference} levels"
    );
    assert!(
        max_channel_difference(&first_frame_pixels, &cli_pixels) > 32,
        "frame 1 and frame {frame} must differ, or the comparison above proves nothing"
    );

    // A broken edit shows the error (file and line) on the page and keeps the last good frame.
    save(&scene, format!("bogus_key = 1\n{original}"));
    let problem = wait_for(
        &client,
        "the scene error on the page",
        "const box = document.getElementById('problem'); \
         return box.hidden ? null : document.getElementById('problem-text').textContent;",
        |v| !v.is_null(),
    )
    .await;
    let problem = problem.as_str().unwrap();
    assert!(
        problem.contains("pool.toml:1:1") && problem.contains("bogus_key"),
        "the page should show file, line and cause: {problem}"
    );
    // A fixed edit recovers: the error goes and the frame is shown from the new scene version.
    save(&scene, &original);
    wait_for(
        &client,
        "the error to clear",
        "return document.getElementById('problem').hidden;",
        |v| v == true,
    )
    .await;
    let previous_generation = shown["generation"].as_str().unwrap().to_string();
    let recovered = wait_for(&client, "the frame after the fix", SHOWN_FRAME, |v| {
        v["frame"] == frame_text
            && v["generation"]
                .as_str()
                .is_some_and(|g| g != previous_generation)
    })
    .await;
    assert_eq!(recovered["frame"], frame.to_string());
    let notice = client
        .find(Locator::Css("#notice"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(notice.contains("reloaded"), "notice {notice:?}");
    assert_eq!(
        max_channel_difference(&shown_pixels(&client).await, &cli_pixels),
        0,
        "the recovered scene shows the same frame"
    );
    client.close().await.unwrap();
}

/// Saves a scene as editors do: a temporary file renamed over the old one.
fn save(path: &Path, contents: impl AsRef<[u8]>) {
    let temporary = path.with_extension("toml.saving");
    std::fs::write(&temporary, contents).unwrap();
    std::fs::rename(&temporary, path).unwrap();
}
