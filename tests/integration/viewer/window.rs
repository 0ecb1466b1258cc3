//! `farfield view` in a real window on a private Xvfb: what the window
//! shows is `farfield render`'s image of the same camera, and real mouse
//! input (xdotool) orbits it.
//!
//! The viewer runs in a child (this test binary again, on [`view_child`],
//! which runs the `farfield` command line in-process), so its window and
//! event loop are a process of their own, as a user's are.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use farfield_tests::scratch;

use super::{PlpRows, bunny_in, camera_of_fragment, have, lit, missing, psnr, reference};
use crate::xvfb::start_xvfb;

/// The child's `farfield` arguments, tab-separated.
const CHILD_ENV: &str = "FARFIELD_VIEW_CHILD_ARGS";
const SIZE: (u32, u32) = (320, 240);
const WAIT: Duration = Duration::from_secs(90);

/// `farfield ARGS` (tab-separated) in a child on `display`, not started.
fn viewer_command(display: &str, args: &str) -> Command {
    let mut command = farfield_tests::child_test("viewer::window::view_child");
    command
        .env(CHILD_ENV, args)
        .env("DISPLAY", display)
        .env_remove("WAYLAND_DISPLAY")
        .env(
            farfield_render::DEVICE_SELECT_OFF.0,
            farfield_render::DEVICE_SELECT_OFF.1,
        );
    command
}

/// The viewer's process, killed when dropped.
pub(super) struct ViewerProcess {
    child: Child,
    lines: Receiver<String>,
}

impl Drop for ViewerProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl ViewerProcess {
    /// `farfield ARGS` (tab-separated) in a child on `display`.
    pub(super) fn spawn(display: &str, args: &str) -> Self {
        let mut child = viewer_command(display, args)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn the viewer");
        let stdout = child.stdout.take().unwrap();
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self { child, lines }
    }

    /// The next line starting with `prefix`, without it.
    pub(super) fn next(&mut self, prefix: &str) -> String {
        let started = Instant::now();
        while started.elapsed() < WAIT {
            match self.lines.recv_timeout(Duration::from_millis(200)) {
                Ok(line) => {
                    if let Some(rest) = line.strip_prefix(prefix) {
                        return rest.to_owned();
                    }
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    if let Ok(Some(status)) = self.child.try_wait() {
                        panic!("the viewer exited ({status}) before printing {prefix:?}");
                    }
                }
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                    panic!("the viewer closed its output before printing {prefix:?}")
                }
            }
        }
        panic!("no {prefix:?} from the viewer in {WAIT:?}");
    }

    /// Interrupts the child as Ctrl-C does; whether it then ended as its
    /// command should, with success, having run its entry point.
    pub(super) fn interrupt(&mut self) -> bool {
        // SAFETY: a plain signal to our own child, which has not been
        // waited for (its pid is still its own).
        unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGINT) };
        let status = self.child.wait().expect("wait for the child");
        let rest: Vec<String> = self.lines.iter().collect();
        status.success() && farfield_tests::child_ran(rest.join("\n").as_bytes())
    }

    /// Waits for the next refined view: its camera and the window's picture.
    fn refined(&mut self) -> (String, Vec<u8>) {
        let camera = self.next("refined camera=");
        let png = self.next("saved png=");
        let (w, h, rgba) = farfield_image::read_png(&png).unwrap();
        assert_eq!((w, h), SIZE, "the window's size");
        (camera, rgba)
    }
}

pub(super) fn xdotool(display: &str, args: &[&str]) -> String {
    let out = Command::new("xdotool")
        .args(args)
        .env("DISPLAY", display)
        .output()
        .expect("xdotool");
    assert!(
        out.status.success(),
        "xdotool {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_owned()
}

#[test]
fn the_window_shows_the_headless_image_and_orbits_under_the_mouse() {
    let Some(xvfb) = start_xvfb() else {
        return missing("the window test needs Xvfb (apt-get install xvfb)");
    };
    if !have("xdotool") {
        return missing("the window test needs xdotool (apt-get install xdotool)");
    }
    let dir = scratch("viewer-window");
    let Some(bunny) = bunny_in(&dir) else {
        return;
    };
    let display = xvfb.display().to_owned();
    let png = dir.join("window.png");
    let start = "eye=0.25,0.2,0.15&target=-0.017,0.11,-0.0015&fov=45";
    let args = [
        "view",
        "--file",
        bunny.to_str().unwrap(),
        "--size",
        "320x240",
        "--no-panel",
        "--camera",
        &start.replace('&', ","),
        "--screenshot-when-refined",
        png.to_str().unwrap(),
    ]
    .join("\t");
    let mut viewer = ViewerProcess::spawn(&display, &args);

    let (camera, first) = viewer.refined();
    assert_eq!(
        camera_of_fragment(&camera),
        camera_of_fragment(start),
        "the window opens at the camera it was given"
    );
    let Some(expected) = reference(&bunny, camera_of_fragment(&camera), SIZE.0, SIZE.1) else {
        return;
    };
    let db = psnr(&expected, &first, SIZE.0, SIZE.1);
    eprintln!("window vs headless: {db:.1} dB, {} lit pixels", lit(&first));
    assert!(lit(&first) > 2000, "the window shows the bunny");
    assert!(
        db >= 30.0,
        "the window differs from the headless render: {db:.1} dB"
    );

    // A real drag across the window: the view orbits and refines again.
    let window = xdotool(&display, &["search", "--name", "farfield"]);
    let window = window
        .lines()
        .next()
        .expect("the viewer's window")
        .to_owned();
    xdotool(&display, &["mousemove", "--window", &window, "160", "120"]);
    xdotool(&display, &["mousedown", "1"]);
    for _ in 0..10 {
        xdotool(&display, &["mousemove_relative", "--", "9", "3"]);
        std::thread::sleep(Duration::from_millis(30));
    }
    xdotool(&display, &["mouseup", "1"]);
    let (moved, second) = viewer.refined();
    assert_ne!(moved, camera, "the drag moved the camera");
    let expected = reference(&bunny, camera_of_fragment(&moved), SIZE.0, SIZE.1).unwrap();
    let db = psnr(&expected, &second, SIZE.0, SIZE.1);
    let change = psnr(&first, &second, SIZE.0, SIZE.1);
    eprintln!("after the drag: {db:.1} dB against headless, {change:.1} dB against before");
    assert!(
        db >= 30.0,
        "after the drag the window differs from the headless render: {db:.1} dB"
    );
    assert!(
        change < 25.0,
        "the picture did not change with the camera ({change:.1} dB)"
    );
}

/// A PLP file in the window with `--plp-budget 2`: it shows what
/// `farfield render --budget 2%` draws, not the whole scene.
#[test]
fn the_window_draws_plp_on_the_budget_it_was_given() {
    let Some(xvfb) = start_xvfb() else {
        return missing("the window test needs Xvfb (apt-get install xvfb)");
    };
    let dir = scratch("viewer-window-plp");
    let Some(rows) = PlpRows::build(&dir, SIZE) else {
        return;
    };
    let png = dir.join("window.png");
    let args = [
        "view",
        "--file",
        rows.file.to_str().unwrap(),
        "--size",
        "320x240",
        "--no-panel",
        "--camera",
        &rows.start.replace('&', ","),
        "--plp-budget",
        &PlpRows::PERCENT.to_string(),
        "--screenshot-when-refined",
        png.to_str().unwrap(),
    ]
    .join("\t");
    let mut viewer = ViewerProcess::spawn(xvfb.display(), &args);
    let (camera, shown) = viewer.refined();
    assert_eq!(camera_of_fragment(&camera), rows.camera);
    rows.check(&shown, SIZE, "the window");
}

/// A window at rest, refined, draws nothing: under 2 % of a core over
/// 10 s, on a file and streamed (it drew the unchanged view four times a
/// second, about a quarter of a core here; a streamed one now sleeps until
/// its connection has news).
#[test]
fn a_window_at_rest_uses_almost_no_cpu() {
    let Some(xvfb) = start_xvfb() else {
        return missing("the window test needs Xvfb (apt-get install xvfb)");
    };
    let dir = scratch("viewer-window-idle");
    let Some(bunny) = bunny_in(&dir) else {
        return;
    };
    let rt = crate::streaming::runtime();
    let server = rt
        .block_on(farfield_memory_server::start(
            farfield_memory_server::ServerConfig::new(&dir, "127.0.0.1:0".parse().unwrap()),
        ))
        .expect("server starts");
    let url = format!("http://{}", server.local_addr());
    let sources = [
        ("file", vec!["--file", bunny.to_str().unwrap()]),
        (
            "streamed",
            vec!["--server", url.as_str(), "--scene", "bunny"],
        ),
    ];
    for (what, source) in sources {
        let png = dir.join(format!("{what}.png"));
        let mut args = vec!["view"];
        args.extend(source);
        args.extend(["--size", "320x240", "--screenshot-when-refined"]);
        args.push(png.to_str().unwrap());
        let mut viewer = ViewerProcess::spawn(xvfb.display(), &args.join("\t"));
        viewer.refined();
        // The screenshot's frame, and the panel settling after it.
        std::thread::sleep(Duration::from_secs(2));
        let ticks = || -> u64 {
            let stat =
                std::fs::read_to_string(format!("/proc/{}/stat", viewer.child.id())).unwrap();
            // utime and stime, fields 14 and 15, after the name in parentheses.
            let fields: Vec<&str> = stat
                .rsplit_once(')')
                .unwrap()
                .1
                .split_whitespace()
                .collect();
            fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap()
        };
        let before = ticks();
        std::thread::sleep(Duration::from_secs(10));
        let used = ticks() - before;
        // Ticks are hundredths of a second: 2 % of a core over 10 s is 20.
        eprintln!("{what} at rest: {used} ticks in 10 s");
        assert!(
            used < 20,
            "{what}: the window at rest used {used} hundredths of a second in 10 s"
        );
    }
    rt.block_on(server.shutdown()).unwrap();
}

/// A scene the server does not have: the window closes by itself and the
/// command fails, saying why (it used to wait, "connecting", for ever).
#[test]
fn an_unknown_scene_ends_the_window_viewer_with_a_message() {
    let Some(xvfb) = start_xvfb() else {
        return missing("the window test needs Xvfb (apt-get install xvfb)");
    };
    let dir = scratch("viewer-window-unknown");
    let rt = crate::streaming::runtime();
    let server = rt.block_on(farfield_memory_server::start(
        farfield_memory_server::ServerConfig::new(&dir, "127.0.0.1:0".parse().unwrap()),
    ));
    let server = server.expect("server starts");
    let args = [
        "view",
        "--server",
        &format!("http://{}", server.local_addr()),
        "--scene",
        "no-such-scene",
        "--size",
        "320x240",
    ]
    .join("\t");
    let mut child = viewer_command(xvfb.display(), &args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn the viewer");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > WAIT {
            let _ = child.kill();
            panic!("the viewer of an unknown scene still runs after {WAIT:?}");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let output = child.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&output.stderr).into_owned()
        + &String::from_utf8_lossy(&output.stdout);
    assert!(!status.success(), "the viewer exited with success: {said}");
    assert!(
        said.contains("no-such-scene") && said.contains("no scene to show"),
        "the viewer did not say why: {said}"
    );
    eprintln!("exited after {:?}", started.elapsed());
    rt.block_on(server.shutdown()).unwrap();
}

/// The child: `farfield` with the arguments in [`CHILD_ENV`], in-process.
#[test]
#[ignore = "subprocess entry point: run by its parent test"]
fn view_child() {
    let Ok(args) = std::env::var(CHILD_ENV) else {
        return;
    };
    use clap::Parser;
    let cli =
        farfield_cli::cli::Cli::try_parse_from(std::iter::once("farfield").chain(args.split('\t')))
            .expect("arguments");
    farfield_cli::cli::run(cli).expect("farfield view");
}
