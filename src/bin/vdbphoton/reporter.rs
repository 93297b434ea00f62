//! How the command line shows a render: progress on stderr, `Saved:`
//! lines on stdout, the summary line.

use crate::one_line;

/// The command line's reporter: progress on stderr (a bar on a terminal, a
/// line every 10 % otherwise, for farm logs), `Saved: 'PATH'` on stdout
/// for every file a finished render writes (the line Flamenco reads).
pub struct CliReporter {
    quiet: bool,
    /// `--progress json`: every event one JSON line on stderr.
    json: bool,
    tty: bool,
    last_decile: std::sync::atomic::AtomicUsize,
    throttle: vdbphoton::render::Throttle,
    /// "frame N: " while a sequence renders.
    frame: std::sync::Mutex<String>,
}

impl vdbphoton::render::Reporter for CliReporter {
    fn warning(&self, m: &str) {
        if self.json {
            return self.emit(serde_json::json!({"event": "warning", "message": m}));
        }
        self.end_bar();
        eprintln!("vdbphoton: warning: {m}");
    }
    fn progress(&self, p: vdbphoton::render::Progress) {
        if self.quiet {
            return;
        }
        if self.json {
            if self.throttle.ready(p.fraction >= 1.0) {
                self.emit(serde_json::json!({
                    "event": "progress",
                    "fraction": p.fraction,
                    "passes": p.passes,
                    "elapsed": p.elapsed,
                    "eta": p.eta,
                }));
            }
            return;
        }
        let eta = p.eta.map_or("?".to_string(), |e| format!("{e:.0}s"));
        let frame = self.frame.lock().map(|f| f.clone()).unwrap_or_default();
        if self.tty {
            if !self.throttle.ready(p.fraction >= 1.0) {
                return;
            }
            let n = ((p.fraction * 30.0) as usize).min(30);
            eprint!(
                "\r{frame}rendering [{}{}] {:5.1}%  pass {}  {:.0}s elapsed, ETA {eta} ",
                "#".repeat(n),
                " ".repeat(30 - n),
                p.fraction * 100.0,
                p.passes + 1,
                p.elapsed
            );
        } else {
            let decile = (p.fraction * 10.0) as usize;
            if decile
                > self
                    .last_decile
                    .fetch_max(decile, std::sync::atomic::Ordering::Relaxed)
            {
                eprintln!(
                    "{frame}rendering: {:3.0}% ({:.1} s elapsed, ETA {eta})",
                    decile as f64 * 10.0,
                    p.elapsed
                );
            }
        }
    }
    fn checkpoint(&self, path: &std::path::Path, passes: u32) {
        if self.json {
            self.emit(serde_json::json!({
                "event": "checkpoint",
                "path": path.display().to_string(),
                "passes": passes,
            }));
        } else if !self.quiet {
            self.end_bar();
            eprintln!("checkpoint: {} after {passes} passes", path.display());
        }
    }
    fn resumed(&self, state: &std::path::Path, passes: u32, seconds: f64) {
        if self.json {
            return self.emit(serde_json::json!({
                "event": "resumed",
                "path": state.display().to_string(),
                "passes": passes,
                "seconds": seconds,
            }));
        }
        self.end_bar();
        eprintln!(
            "resumed: '{}' after {passes} passes ({seconds:.1} s)",
            state.display()
        );
    }
    fn saved(&self, path: &std::path::Path) {
        self.end_bar();
        println!("Saved: '{}'", path.display());
        let _ = std::io::Write::flush(&mut std::io::stdout());
        if self.json {
            self.emit(serde_json::json!({"event": "saved", "path": path.display().to_string()}));
        }
    }
    fn frame_started(&self, frame: u32, index: usize, count: usize) {
        if self.json {
            self.emit(serde_json::json!({
                "event": "frame",
                "frame": frame,
                "index": index,
                "count": count,
            }));
        }
        self.last_decile
            .store(0, std::sync::atomic::Ordering::Relaxed);
        if let Ok(mut f) = self.frame.lock() {
            *f = format!("frame {frame} ({}/{count}): ", index + 1);
        }
    }
    fn frame_done(&self, frame: u32, outcome: &vdbphoton::frames::FrameOutcome, seconds: f64) {
        use vdbphoton::frames::FrameOutcome;
        self.end_bar();
        match outcome {
            FrameOutcome::Written(s) => {
                eprintln!("frame {frame}: {} ({seconds:.2} s)", summary_line(s))
            }
            FrameOutcome::Skipped(p) => {
                eprintln!("frame {frame}: skipped, '{}' exists", p.display())
            }
            FrameOutcome::Failed(e) => {
                eprintln!("vdbphoton: error: frame {frame}: {}", one_line(e))
            }
        }
    }
}

impl CliReporter {
    /// A reporter for stderr (a bar when it is a terminal); `quiet`: no
    /// progress; `json`: JSON lines.
    pub fn new(quiet: bool, json: bool) -> Self {
        use std::io::IsTerminal;
        CliReporter {
            quiet,
            json,
            tty: !json && std::io::stderr().is_terminal(),
            last_decile: std::sync::atomic::AtomicUsize::new(0),
            throttle: vdbphoton::render::Throttle::new(std::time::Duration::from_millis(200)),
            frame: std::sync::Mutex::new(String::new()),
        }
    }

    /// One JSON event, one line (`--progress json`).
    fn emit(&self, v: serde_json::Value) {
        eprintln!("{v}");
    }

    /// Ends a progress bar's line before other output.
    fn end_bar(&self) {
        if self.tty && !self.quiet {
            eprint!("\r\x1b[K");
        }
    }
}

pub fn summary_line(s: &vdbphoton::render::Summary) -> String {
    format!(
        "rendered {} x {} with {} ({} passes, {} spp) in {:.2} s  (load {:.2} s, write {:.2} s, {} threads)",
        s.width,
        s.height,
        s.integrator,
        s.passes,
        s.spp,
        s.render_seconds,
        s.load_seconds,
        s.write_seconds,
        s.threads
    )
}
