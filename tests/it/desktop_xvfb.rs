//! The real desktop binary under a virtual X display: started with no arguments, screenshotted with ImageMagick,
//! and checked to show the side panel and voxels (not a blank or black window). Needs `Xvfb` and `import`;
//! `tests/run.sh` installs them as root. Without them the test is skipped loudly (a failure under `CI=true`).

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Kill(Child);

impl Drop for Kill {
    fn drop(&mut self) {
        // SIGTERM first, so Xvfb removes its lock file; SIGKILL only if it does not go.
        let _ = Command::new("kill").arg(self.0.id().to_string()).status();
        for _ in 0..20 {
            if self.0.try_wait().is_ok_and(|s| s.is_some()) {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn have(tool: &str) -> bool {
    Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {tool}"))
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn desktop_app_shows_panel_and_voxels() {
    if !(have("Xvfb") && have("import")) {
        crate::common::skip("desktop test", "Xvfb and ImageMagick's import are needed");
        return;
    }
    // Xvfb picks a free display and writes its number to stdout (-displayfd) once it accepts connections: a
    // fixed number can collide with another server or with the lock file a killed one left behind.
    let mut xvfb = Kill(
        Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "1280x800x24", "-nolisten", "tcp"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start Xvfb"),
    );
    let mut number = String::new();
    let stdout = xvfb.0.stdout.take().expect("Xvfb's stdout");
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut number).expect("Xvfb's display number");
    let display = format!(":{}", number.trim());
    assert!(display.len() > 1, "Xvfb gave no display number");
    let app = Kill(
        Command::new(env!("CARGO_BIN_EXE_meshvox"))
            .env("DISPLAY", &display)
            .env_remove("WAYLAND_DISPLAY")
            .stderr(Stdio::piped())
            .spawn()
            .expect("start meshvox"),
    );
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("desktop.png");
    let started = Instant::now();
    let mut last = String::new();
    while started.elapsed() < Duration::from_secs(90) {
        std::thread::sleep(Duration::from_secs(2));
        let ok = Command::new("import")
            .args(["-display", display.as_str(), "-window", "root"])
            .arg(&shot)
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            continue;
        }
        let Ok(img) = image::open(&shot) else { continue };
        let img = img.to_rgb8();
        // The window is 1200x760 points at the top left; the panel is the left 260 points of it.
        let (panel, view) = (region(&img, 0, 0, 250, 700), region(&img, 300, 50, 1150, 700));
        let panel_light = panel.iter().filter(|p| p.iter().all(|&c| c > 150)).count() as f64 / panel.len() as f64;
        let orange = view.iter().filter(|p| p[0] > 90 && p[0] > p[1] + 30 && p[0] > p[2] + 60).count() as f64
            / view.len() as f64;
        last = format!("panel text pixels {:.2}%, orange voxel pixels {:.2}%", panel_light * 100.0, orange * 100.0);
        if panel_light > 0.003 && orange > 0.02 {
            eprintln!("desktop screenshot {}: {last}", shot.display());
            drop(app);
            return;
        }
    }
    let mut app = app;
    let _ = app.0.kill();
    let output = std::mem::replace(&mut app.0, Command::new("true").spawn().expect("true")).wait_with_output();
    let stderr = output.map(|o| String::from_utf8_lossy(&o.stderr).into_owned()).unwrap_or_default();
    let tail: Vec<&str> = stderr.lines().rev().take(15).collect();
    panic!(
        "after 90 s the window does not show the panel and voxels ({last}); screenshot: {}\napp stderr (last lines):\n{}",
        shot.display(),
        tail.into_iter().rev().collect::<Vec<_>>().join("\n")
    );
}

fn region(img: &image::RgbImage, x0: u32, y0: u32, x1: u32, y1: u32) -> Vec<[u8; 3]> {
    let (w, h) = img.dimensions();
    let mut out = Vec::new();
    for y in y0..y1.min(h) {
        for x in x0..x1.min(w) {
            out.push(img.get_pixel(x, y).0);
        }
    }
    out
}
