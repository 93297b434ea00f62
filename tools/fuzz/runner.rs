//! One input in one child process, with an address-space limit, no core
//! dumps and a wall-clock limit; its exit status, time and peak memory
//! (`wait4`'s resource usage), so that a crash in C++ ends only the child.
//!
//! Two times are kept. `seconds` is the campaign's, from starting the
//! launcher to reaping it: two process starts. `own_seconds` is the
//! target's alone, measured by the launcher from spawning it to reaping
//! it: what a user who runs the refused command waits for.

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How a child ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    Exit(i32),
    Signal(i32),
    /// Killed after the time limit.
    Killed,
}

#[derive(Debug, Clone)]
pub struct Outcome {
    pub status: Status,
    pub seconds: f64,
    /// The target process's own wall time (one process start, spawned by
    /// the launcher); `None` if the launcher was killed first.
    pub own_seconds: Option<f64>,
    /// The target's user + system CPU time.
    pub cpu_seconds: Option<f64>,
    /// Peak resident memory in bytes.
    pub max_rss: u64,
    pub stdout: String,
    pub stderr: String,
}

pub struct Limits {
    pub seconds: f64,
    /// Address-space limit (`RLIMIT_AS`) in bytes.
    pub address_space: u64,
}

/// Sets an address-space limit and no core dumps on this process (a
/// launcher: its child inherits them).
fn limit_self(address_space: u64) {
    let set = |res, v: u64| {
        let lim = libc::rlimit {
            rlim_cur: v,
            rlim_max: v,
        };
        // SAFETY: a plain system call with a valid pointer.
        unsafe { libc::setrlimit(res, &lim) };
    };
    set(libc::RLIMIT_AS, address_space);
    set(libc::RLIMIT_CORE, 0);
}

/// Waits for `pid`; kills its process group after `limit`. Returns the
/// wait status, whether it was killed, and its resource usage.
fn wait_for(pid: libc::pid_t, limit: Option<Duration>) -> (i32, bool, libc::rusage) {
    let t0 = Instant::now();
    let mut status = 0;
    // SAFETY: zeroed rusage is a valid value for wait4 to fill.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let mut killed = false;
    let mut nap = Duration::from_micros(200);
    loop {
        let flags = if limit.is_some() { libc::WNOHANG } else { 0 };
        // SAFETY: pid is our child; status and usage are valid pointers.
        let r = unsafe { libc::wait4(pid, &mut status, flags, &mut usage) };
        if r == pid {
            return (status, killed, usage);
        }
        if r < 0 {
            panic!("wait4 failed: {}", std::io::Error::last_os_error());
        }
        if let Some(l) = limit {
            if !killed && t0.elapsed() > l {
                // SAFETY: signals our own child's process group.
                unsafe { libc::kill(-pid, libc::SIGKILL) };
                killed = true;
            }
        }
        std::thread::sleep(nap);
        nap = (nap * 2).min(Duration::from_millis(5));
    }
}

/// The launcher (`vdbfuzz exec REPORT AS -- PROGRAM ARGS`): runs the
/// program under the limits and writes its exit code, signal and peak
/// memory to REPORT. Peak memory has to be measured here: `wait4` of a
/// child forked from the campaign would count the campaign's own memory,
/// which a child holds until it calls exec.
pub fn launcher(args: &[String]) -> std::process::ExitCode {
    let [report, aspace, dashes, program, rest @ ..] = args else {
        eprintln!("usage: vdbfuzz exec REPORT ADDRESS_SPACE -- PROGRAM ARGS");
        return std::process::ExitCode::from(2);
    };
    assert_eq!(dashes, "--");
    limit_self(aspace.parse().expect("address space"));
    let t0 = Instant::now();
    let child = match Command::new(program).args(rest).spawn() {
        Ok(c) => c,
        Err(e) => {
            eprintln!("vdbfuzz: cannot start {program}: {e}");
            return std::process::ExitCode::from(2);
        }
    };
    let (status, _, usage) = wait_for(child.id() as libc::pid_t, None);
    let own = t0.elapsed().as_secs_f64();
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let cpu = tv(usage.ru_utime) + tv(usage.ru_stime);
    let (code, signal) = if libc::WIFEXITED(status) {
        (libc::WEXITSTATUS(status), 0)
    } else {
        (-1, libc::WTERMSIG(status))
    };
    std::fs::write(
        report,
        format!("{code} {signal} {} {own:.6} {cpu:.6}", usage.ru_maxrss),
    )
    .expect("report");
    std::process::ExitCode::SUCCESS
}

/// Runs `program args` through the launcher, with its output in files of
/// `scratch` (a pipe could fill and stall the child).
pub fn run(
    program: &Path,
    args: &[std::ffi::OsString],
    env: &[(&str, &str)],
    scratch: &Path,
    limits: &Limits,
) -> Outcome {
    let out_path = scratch.join("stdout");
    let err_path = scratch.join("stderr");
    let report = scratch.join("report");
    let _ = std::fs::remove_file(&report);
    let out = std::fs::File::create(&out_path).expect("scratch stdout");
    let err = std::fs::File::create(&err_path).expect("scratch stderr");
    let mut cmd = Command::new(std::env::current_exe().expect("own path"));
    cmd.arg("exec")
        .arg(&report)
        .arg(limits.address_space.to_string())
        .arg("--")
        .arg(program)
        .args(args)
        .envs(env.iter().copied())
        .env("RUST_BACKTRACE", "0")
        .process_group(0)
        .stdin(Stdio::null())
        .stdout(Stdio::from(out))
        .stderr(Stdio::from(err));
    let t0 = Instant::now();
    let child = cmd.spawn().expect("start the launcher");
    let limit = Duration::from_secs_f64(limits.seconds);
    let (_, killed, _) = wait_for(child.id() as libc::pid_t, Some(limit));
    let seconds = t0.elapsed().as_secs_f64();
    drop(child);
    let rep = std::fs::read_to_string(&report).unwrap_or_default();
    let v: Vec<f64> = rep
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect();
    let status = match (killed, v.as_slice()) {
        (true, _) | (_, []) => Status::Killed,
        (_, [_, s, ..]) if *s != 0.0 => Status::Signal(*s as i32),
        (_, [c, ..]) => Status::Exit(*c as i32),
    };
    let read = |p: &Path| {
        let b = std::fs::read(p).unwrap_or_default();
        String::from_utf8_lossy(&b[..b.len().min(1 << 16)]).into_owned()
    };
    Outcome {
        status,
        seconds,
        own_seconds: v.get(3).copied().filter(|_| !killed),
        cpu_seconds: v.get(4).copied().filter(|_| !killed),
        max_rss: v.get(2).copied().unwrap_or(0.0) as u64 * 1024,
        stdout: read(&out_path),
        stderr: read(&err_path),
    }
}
