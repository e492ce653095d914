//! Runs of the meshvox binary bounded as a run on a hostile file must be, so that a regression (an unbounded read,
//! a hang) fails the test instead of exhausting the machine. (Apart from `common.rs`, which the fuzz targets include
//! and where the binary's path is not defined.)

/// The bounds a run on a hostile file must stay within: its address space (so that an unbounded read fails
/// the run with an allocation failure instead of exhausting the machine), its CPU time (independent of how
/// busy the test machine is) and, for a run that waits without using the CPU (a FIFO), its wall time.
pub struct Bounds {
    pub address_space: u64,
    pub cpu_seconds: u64,
    pub wall: std::time::Duration,
}

impl Bounds {
    /// For a run that refuses or loads a small file: 1 GiB of address space (the binary, its threads' stacks
    /// and a small mesh fit many times over), one CPU second, and 30 s of wall time.
    pub const HOSTILE: Bounds =
        Bounds { address_space: 1 << 30, cpu_seconds: 1, wall: std::time::Duration::from_secs(30) };
}

/// Runs the meshvox binary with `args` in `dir` within `bounds` (`ulimit -v` and `ulimit -t` through `sh`, and
/// a kill at the wall limit). Panics, naming the run, when it had to be killed or died of a limit.
pub fn meshvox_bounded(args: &[&str], dir: &std::path::Path, bounds: &Bounds) -> std::process::Output {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let script =
        format!("ulimit -v {} && ulimit -t {} && exec \"$0\" \"$@\"", bounds.address_space / 1024, bounds.cpu_seconds);
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_meshvox"))
        .args(args)
        .current_dir(dir)
        // glibc reserves 64 MiB of address space per malloc arena, and makes up to 8 per core.
        .env("MALLOC_ARENA_MAX", "2")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start meshvox under sh");
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_end(&mut bytes);
            }
            bytes
        })
    };
    let stdout = drain(child.stdout.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let stderr = drain(child.stderr.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for meshvox") {
            break status;
        }
        if started.elapsed() > bounds.wall {
            let _ = child.kill();
            let _ = child.wait();
            panic!("meshvox {args:?} still ran after {:?}: killed (a hang)", bounds.wall);
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    let output =
        std::process::Output { status, stdout: stdout.join().expect("stdout"), stderr: stderr.join().expect("stderr") };
    let died = {
        use std::os::unix::process::ExitStatusExt;
        output.status.signal()
    };
    if let Some(signal) = died {
        // 24 is SIGXCPU (the CPU limit); 6 (SIGABRT) is an allocation that failed under the address-space limit.
        panic!(
            "meshvox {args:?} was killed by signal {signal} within {} GiB of address space and {} CPU s: {}",
            bounds.address_space >> 30,
            bounds.cpu_seconds,
            String::from_utf8_lossy(&output.stderr)
        );
    }
    output
}
