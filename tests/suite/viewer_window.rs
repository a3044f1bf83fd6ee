//! The interactive viewer in a real window: `btfsynth view` on a virtual X display (Xvfb),
//! screenshots of its window (ImageMagick's `import`) and keys typed into it (`xdotool`).
//!
//! Skipped with one printed line where Xvfb, import or xdotool is missing, unless
//! `BTFSYNTH_REQUIRE_XVFB=1` (set by CI) makes that a failure. Like the headless GPU
//! tests, a machine without any wgpu adapter skips only with `BTFSYNTH_SKIP_GPU=1`.

use crate::common;

use btfsynth::testdata::announce_skip;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const TOOLS: [&str; 3] = ["Xvfb", "import", "xdotool"];

fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
}

/// Kills the child processes it holds when the test ends, however it ends.
struct Children(Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Starts Xvfb on a free display number and waits for its socket.
fn start_xvfb(children: &mut Children) -> String {
    let number =
        (90..200).find(|n| !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()).expect("a free display");
    let display = format!(":{number}");
    let child = Command::new("Xvfb")
        .args([&display, "-screen", "0", "640x480x24", "-nolisten", "tcp"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("Xvfb starts");
    children.0.push(child);
    let socket = PathBuf::from(format!("/tmp/.X11-unix/X{number}"));
    wait_for("Xvfb's socket", Duration::from_secs(20), || socket.exists().then_some(()));
    display
}

/// Polls `f` every 250 ms until it returns something or `limit` passes.
fn wait_for<T>(what: &str, limit: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let started = Instant::now();
    loop {
        if let Some(t) = f() {
            return t;
        }
        if started.elapsed() > limit {
            let log = VIEWER_LOG.get().and_then(|l| std::fs::read_to_string(l).ok()).unwrap_or_default();
            panic!("timed out after {limit:?} waiting for {what}; the viewer said: {log}");
        }
        std::thread::sleep(Duration::from_millis(250));
    }
}

/// The viewer's stderr, quoted when the test times out.
static VIEWER_LOG: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();

fn x_tool(display: &str, tool: &str, args: &[&str]) -> std::process::Output {
    Command::new(tool).args(args).env("DISPLAY", display).output().expect("the X tool runs")
}

/// The viewer's window: the one named "btfsynth view" whose screenshot has the size asked.
fn find_window(display: &str, size: (u32, u32)) -> Option<String> {
    let found = x_tool(display, "xdotool", &["search", "--name", "btfsynth view"]);
    let ids = String::from_utf8_lossy(&found.stdout).to_string();
    ids.split_whitespace()
        .find(|id| screenshot(display, id).is_some_and(|s| s.dimensions() == size))
        .map(String::from)
}

/// A screenshot of window `id` as RGB.
fn screenshot(display: &str, id: &str) -> Option<image::RgbImage> {
    let out = x_tool(display, "import", &["-window", id, "png:-"]);
    if !out.status.success() {
        return None;
    }
    image::load_from_memory(&out.stdout).ok().map(|i| i.into_rgb8())
}

/// Pixels unlike the background (the bottom-right corner, which the model never reaches).
fn model_pixels(image: &image::RgbImage) -> usize {
    let background = image.get_pixel(image.width() - 1, image.height() - 1).0;
    image.pixels().filter(|p| p.0.iter().zip(background).any(|(a, b)| a.abs_diff(b) > 20)).count()
}

/// Mean absolute difference per channel, in 8-bit levels.
fn mean_difference(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    let sum: u64 = a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| x.abs_diff(*y) as u64).sum();
    sum as f64 / a.as_raw().len() as f64
}

/// Pure white pixels in the top-left corner, where the overlay's text is.
fn overlay_text_pixels(image: &image::RgbImage) -> usize {
    (0..24)
        .flat_map(|y| (0..120).map(move |x| (x, y)))
        .filter(|&(x, y)| image.get_pixel(x, y).0 == [255; 3])
        .count()
}

fn press(display: &str, window: &str, key: &str) {
    x_tool(display, "xdotool", &["windowfocus", "--sync", window]);
    let out = x_tool(display, "xdotool", &["key", key]);
    assert!(out.status.success(), "xdotool key {key}: {}", String::from_utf8_lossy(&out.stderr));
}

/// The next screenshot that differs from `before` by more than `threshold` levels, within
/// 60 s.
/// The window's picture once two screenshots 2 s apart agree.
fn standing_picture(display: &str, window: &str, what: &str) -> image::RgbImage {
    wait_for(what, Duration::from_secs(90), || {
        let a = screenshot(display, window)?;
        std::thread::sleep(Duration::from_secs(2));
        let b = screenshot(display, window)?;
        (mean_difference(&a, &b) < 0.2).then_some(b)
    })
}

fn next_screenshot(display: &str, window: &str, before: &image::RgbImage, threshold: f64) -> image::RgbImage {
    let mut last = 0.0;
    wait_for(&format!("the window to change (by {last:.2} levels so far)"), Duration::from_secs(60), || {
        let shot = screenshot(display, window)?;
        last = mean_difference(&shot, before);
        (last > threshold).then_some(shot)
    })
}

#[test]
fn the_viewer_draws_the_model_in_a_window_and_answers_keys() {
    if let Some(missing) = TOOLS.iter().find(|t| !on_path(t)) {
        let why = format!("{missing} is not installed (apt-get install xvfb imagemagick xdotool)");
        assert!(std::env::var("BTFSYNTH_REQUIRE_XVFB").map_or(true, |v| v != "1"), "the window test: {why}");
        announce_skip("the window test", &why);
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel_crop(dir.path(), "analysis");
    let surface = dir.path().join("bunny.ply");
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    let r = common::btfsynth(&[
        "-q",
        "synth",
        analysis.to_str().unwrap(),
        bunny,
        "--vertices",
        "3000",
        "-o",
        surface.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let saves = dir.path().join("saves");
    std::fs::create_dir(&saves).unwrap();

    let mut children = Children(Vec::new());
    let display = start_xvfb(&mut children);
    let log = dir.path().join("viewer.log");
    VIEWER_LOG.set(log.clone()).unwrap();
    let viewer = Command::new(env!("CARGO_BIN_EXE_btfsynth"))
        .args(["view", surface.to_str().unwrap(), "--size", "320x240", "--save-dir", saves.to_str().unwrap()])
        .env("DISPLAY", &display)
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .expect("the viewer starts");
    children.0.push(viewer);
    let window = wait_for("the viewer's window", Duration::from_secs(120), || {
        if let Ok(Some(status)) = children.0[1].try_wait() {
            let stderr = std::fs::read_to_string(&log).unwrap_or_default();
            if stderr.contains("no GPU adapter found")
                && std::env::var("BTFSYNTH_SKIP_GPU").is_ok_and(|v| v == "1")
            {
                return Some(None);
            }
            panic!("the viewer exited ({status}): {stderr}");
        }
        find_window(&display, (320, 240)).map(Some)
    });
    let Some(window) = window else {
        announce_skip("the window test", "BTFSYNTH_SKIP_GPU=1 and no GPU adapter");
        return;
    };

    // The model is drawn (a twentieth of the window unlike the background), under the
    // overlay. Counting colours instead failed on grey materials (172 colours in all).
    // Mesa's software drivers compile the shaders on the first frame (1.2 s here; far
    // longer on a busy machine with a cold shader cache).
    let started = Instant::now();
    let shows_model = |s: &image::RgbImage| model_pixels(s) > 320 * 240 / 20;
    wait_for("the model on screen", Duration::from_secs(180), || {
        screenshot(&display, &window).filter(|s| shows_model(s) && overlay_text_pixels(s) > 20)
    });
    eprintln!("the first frame showed after {:.1} s", started.elapsed().as_secs_f64());

    // O hides the overlay; Up raises the light by 5° a press, so nine bring it overhead,
    // where its orbit no longer moves it: the picture stands still.
    press(&display, &window, "o");
    wait_for("the overlay to go", Duration::from_secs(60), || {
        screenshot(&display, &window).filter(|s| overlay_text_pixels(s) == 0)
    });
    for _ in 0..9 {
        press(&display, &window, "Up");
    }
    let still = standing_picture(&display, &window, "the picture to stand still");

    // T: texton false colour, a different picture. On a loaded machine the first changed
    // screenshot can be a frame still being drawn, so the comparison waits for it to settle.
    press(&display, &window, "t");
    next_screenshot(&display, &window, &still, 2.0);
    let textons = standing_picture(&display, &window, "the texton picture to stand still");
    eprintln!("T changed the window by {:.1} levels on average", mean_difference(&still, &textons));

    // S saves the frame at the window's size.
    press(&display, &window, "s");
    let saved = saves.join("view-0000.png");
    wait_for("the saved frame", Duration::from_secs(60), || saved.is_file().then_some(()));
    let frame = image::open(&saved).unwrap().into_rgb8();
    assert_eq!(frame.dimensions(), (320, 240));
    assert!(shows_model(&frame), "the saved frame shows the model");
    assert!(mean_difference(&frame, &textons) < 8.0, "the saved frame is what the window shows");
}
