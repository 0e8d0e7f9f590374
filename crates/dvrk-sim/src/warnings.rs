//! The live twin's warnings, said without ever blocking its loop.
//!
//! Why: `dvrk serve` refuses bad commands with a warning, and a client may send thousands a
//! second. Written straight to stderr from the real-time loop, a flood blocks the loop as soon
//! as nobody reads the pipe (a launcher, systemd, Python's `subprocess.PIPE`: after its 64 KiB
//! the write waits for ever): `measured_js` stops and valid commands are no longer taken. So:
//!
//! - a [`Limiter`] lets a few lines a second through verbatim ([`Limiter::BURST`]) and sums up
//!   the rest once a second, grouped by topic and reason ("401 commands refused in the last
//!   second, 5 shown: 401 /PSM1/servo_jp (wrong length)");
//! - what it lets through goes to stderr through a [`LineQueue`]: a bounded queue drained by a
//!   thread of its own, which alone writes (and alone waits when the pipe is full). The loop
//!   only `try_send`s: when the queue is full the line is dropped and counted, never waited for;
//! - [`Warnings`] puts the two together for the loop, and hands each line it says to a second
//!   sink (`/rosout`), which must not block either (the caller's: [`crate::ros2::Ros2::log_line`]
//!   writes with no blocking time).
//!
//! The limiter reads no clock of its own (`now` is given, in seconds from any origin), so its
//! tests are deterministic.

use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Rate limiting of one stream of warnings: the first [`Limiter::BURST`] lines of each window
/// said as they are, the rest counted by group and summed up in one line when the window ends.
#[derive(Debug, Clone)]
pub struct Limiter {
    /// What a warning is, in the plural ("commands refused").
    what: &'static str,
    /// The window (s).
    window: f64,
    /// Lines said verbatim per window.
    burst: u32,
    /// The current window's start (s), once a warning came.
    start: Option<f64>,
    /// Warnings in the current window, and how many of them were said verbatim.
    total: u64,
    shown: u64,
    /// The current window's warnings by group, in the order the groups first came.
    groups: Vec<(String, u64)>,
    /// Warnings never said one by one (only in a summary), over the whole run.
    summarised: u64,
}

impl Limiter {
    /// Lines said verbatim per window.
    pub const BURST: u32 = 5;
    /// Distinct groups a summary names; the rest are lumped together.
    const MAX_GROUPS: usize = 16;

    /// A limiter of `what` (plural: "commands refused") over windows of `window` seconds,
    /// [`Limiter::BURST`] lines verbatim in each.
    pub fn new(what: &'static str, window: f64) -> Limiter {
        Limiter { what, window, burst: Self::BURST, start: None, total: 0, shown: 0, groups: Vec::new(), summarised: 0 }
    }

    /// A warning at `now` (s) in `group` (what the summary counts it under): `line` is said
    /// through `say` when the window still has room, counted for its summary otherwise. A
    /// window that ended before `now` is summed up first.
    pub fn offer(&mut self, now: f64, group: &str, line: &str, say: &mut impl FnMut(&str)) {
        self.tick(now, say);
        if self.start.is_none() {
            self.start = Some(now);
        }
        self.total += 1;
        if self.shown < u64::from(self.burst) {
            self.shown += 1;
            say(line);
        } else {
            self.summarised += 1;
        }
        let known = self.groups.iter().any(|(g, _)| g == group);
        let key = if known || self.groups.len() < Self::MAX_GROUPS { group } else { "others" };
        match self.groups.iter_mut().find(|(g, _)| g == key) {
            Some((_, n)) => *n += 1,
            None => self.groups.push((key.to_string(), 1)),
        }
    }

    /// Whether a summary is due when the window ends (some warnings were not said).
    pub fn pending(&self) -> bool {
        self.total > self.shown
    }

    /// End the window if it is over at `now` (s): its summary through `say` when some of its
    /// warnings were not said.
    pub fn tick(&mut self, now: f64, say: &mut impl FnMut(&str)) {
        if let Some(start) = self.start {
            if now - start >= self.window {
                self.close(self.window, say);
            }
        }
    }

    /// Sum up the window under way, however short (at the end of a run).
    pub fn flush(&mut self, now: f64, say: &mut impl FnMut(&str)) {
        if let Some(start) = self.start {
            self.close((now - start).clamp(0.0, self.window), say);
        }
    }

    /// Warnings said only in a summary, over the whole run.
    pub fn summarised(&self) -> u64 {
        self.summarised
    }

    fn close(&mut self, span: f64, say: &mut impl FnMut(&str)) {
        if self.pending() {
            let last = if span >= self.window && self.window == 1.0 { "the last second".to_string() } else { format!("the last {span:.2} s") };
            let groups: Vec<String> = self.groups.iter().map(|(g, n)| format!("{n} {g}")).collect();
            say(&format!("{} {} in {last}, {} shown: {}", self.total, self.what, self.shown, groups.join(", ")));
        }
        self.start = None;
        self.total = 0;
        self.shown = 0;
        self.groups.clear();
    }
}

/// Lines written by a thread of their own through a bounded queue: [`LineQueue::send`] never
/// waits; a line the queue has no room for is dropped and counted.
#[derive(Debug)]
pub struct LineQueue {
    tx: Option<SyncSender<String>>,
    /// Lines queued, and lines refused by a full (or closed) queue.
    queued: u64,
    dropped: u64,
    /// Lines the thread wrote (whole, without error).
    written: Arc<AtomicU64>,
    /// Says when the thread has written everything and ended.
    done: Receiver<()>,
}

impl LineQueue {
    /// Lines the queue holds while its writer waits.
    pub const CAPACITY: usize = 64;

    /// Start the writer thread: each line, with a newline, in one write to `out`.
    pub fn spawn(mut out: impl Write + Send + 'static) -> LineQueue {
        let (tx, rx) = sync_channel::<String>(Self::CAPACITY);
        let (done_tx, done) = sync_channel::<()>(1);
        let written = Arc::new(AtomicU64::new(0));
        let count = written.clone();
        // Without the thread (none could be started) the queue has no reader: every line is
        // dropped and counted, and the loop goes on.
        let _ = std::thread::Builder::new().name("dvrk-warnings".into()).spawn(move || {
            for mut line in rx {
                line.push('\n');
                if out.write_all(line.as_bytes()).and_then(|()| out.flush()).is_ok() {
                    count.fetch_add(1, Ordering::Relaxed);
                }
            }
            let _ = done_tx.send(());
        });
        LineQueue { tx: Some(tx), queued: 0, dropped: 0, written, done }
    }

    /// Queue `line` (without its newline) if there is room; drop and count it otherwise.
    pub fn send(&mut self, line: String) {
        match self.tx.as_ref().map(|tx| tx.try_send(line)) {
            Some(Ok(())) => self.queued += 1,
            Some(Err(TrySendError::Full(_) | TrySendError::Disconnected(_))) | None => self.dropped += 1,
        }
    }

    /// Close the queue and give the thread up to `wait` to write what it holds; the lines that
    /// were not written (dropped, still queued, or failed) are counted. The thread is not
    /// waited for beyond `wait`: a writer blocked for ever ends with the process.
    pub fn finish(mut self, wait: Duration) -> u64 {
        drop(self.tx.take());
        let _ = self.done.recv_timeout(wait);
        self.dropped + self.queued.saturating_sub(self.written.load(Ordering::Relaxed))
    }
}

/// What became of a run's warnings.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WarningCounts {
    /// Warnings said only in a once-a-second summary, not one by one.
    pub summarised: u64,
    /// Lines (verbatim or summaries) that did not reach stderr: no room in the queue, or not
    /// written by the end of the run.
    pub stderr_dropped: u64,
    /// Lines the second sink (`/rosout`) could not take at once.
    pub rosout_dropped: u64,
}

/// A loop's warnings: rate-limited ([`Limiter`]), then to stderr through a [`LineQueue`] (as
/// `warning: ...`) and to a second sink given on each call, which says whether it took the line.
#[derive(Debug)]
pub struct Warnings {
    limiter: Limiter,
    stderr: LineQueue,
    start: Instant,
    rosout_dropped: u64,
}

impl Warnings {
    /// How long [`Warnings::finish`] waits for the last lines to be written.
    pub const FINISH_WAIT: Duration = Duration::from_millis(250);

    /// Warnings of `what` ("commands refused"), written to `out` (stderr) off the caller's thread.
    pub fn new(what: &'static str, out: impl Write + Send + 'static) -> Warnings {
        Warnings { limiter: Limiter::new(what, 1.0), stderr: LineQueue::spawn(out), start: Instant::now(), rosout_dropped: 0 }
    }

    /// A warning in `group`: said now on both sinks if the limiter lets it, counted otherwise.
    pub fn warn(&mut self, group: &str, line: &str, rosout: impl FnMut(&str) -> bool) {
        let now = self.start.elapsed().as_secs_f64();
        let (limiter, mut say) = self.sinks(rosout);
        limiter.offer(now, group, line, &mut say);
    }

    /// Say the summary of a window that is over (cheap when none is due: call it every step).
    pub fn tick(&mut self, rosout: impl FnMut(&str) -> bool) {
        if self.limiter.pending() {
            let now = self.start.elapsed().as_secs_f64();
            let (limiter, mut say) = self.sinks(rosout);
            limiter.tick(now, &mut say);
        }
    }

    /// Sum up the last window, let the writer finish (within [`Warnings::FINISH_WAIT`]) and count.
    pub fn finish(mut self, rosout: impl FnMut(&str) -> bool) -> WarningCounts {
        let now = self.start.elapsed().as_secs_f64();
        {
            let (limiter, mut say) = self.sinks(rosout);
            limiter.flush(now, &mut say);
        }
        let summarised = self.limiter.summarised();
        WarningCounts { summarised, stderr_dropped: self.stderr.finish(Self::FINISH_WAIT), rosout_dropped: self.rosout_dropped }
    }

    /// The limiter, and the sink of what it says: stderr's queue and `rosout`.
    fn sinks<'a>(&'a mut self, mut rosout: impl FnMut(&str) -> bool + 'a) -> (&'a mut Limiter, impl FnMut(&str) + 'a) {
        let (stderr, dropped) = (&mut self.stderr, &mut self.rosout_dropped);
        let say = move |line: &str| {
            stderr.send(format!("warning: {line}"));
            if !rosout(line) {
                *dropped += 1;
            }
        };
        (&mut self.limiter, say)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn said(l: &mut Limiter, now: f64, group: &str, line: &str) -> Vec<String> {
        let mut out = Vec::new();
        l.offer(now, group, line, &mut |s: &str| out.push(s.to_string()));
        out
    }

    #[test]
    fn a_flood_is_said_a_few_lines_a_second_then_summed_up_by_group() {
        let mut l = Limiter::new("commands refused", 1.0);
        let mut lines = Vec::new();
        // 401 refusals within the first second: 400 wrong lengths and one NaN on the jaw.
        for i in 0..400 {
            lines.extend(said(&mut l, i as f64 * 0.002, "/PSM1/servo_jp (wrong length)", &format!("bad {i}")));
        }
        lines.extend(said(&mut l, 0.9, "/PSM1/jaw/servo_jp (not finite)", "nan"));
        assert_eq!(lines, ["bad 0", "bad 1", "bad 2", "bad 3", "bad 4"]);
        assert!(l.pending());
        // Nothing more until the window ends; then one line.
        let mut summary = Vec::new();
        l.tick(0.999, &mut |s: &str| summary.push(s.to_string()));
        assert!(summary.is_empty());
        l.tick(1.0, &mut |s: &str| summary.push(s.to_string()));
        assert_eq!(summary, ["401 commands refused in the last second, 5 shown: 400 /PSM1/servo_jp (wrong length), 1 /PSM1/jaw/servo_jp (not finite)"]);
        assert!(!l.pending());
        assert_eq!(l.summarised(), 396);
        // A new window: verbatim again; a quiet window that ends says nothing.
        assert_eq!(said(&mut l, 1.5, "g", "again"), ["again"]);
        let mut quiet = Vec::new();
        l.tick(3.0, &mut |s: &str| quiet.push(s.to_string()));
        assert!(quiet.is_empty());
    }

    #[test]
    fn a_window_that_ended_is_summed_up_before_the_next_warning_and_flush_sums_up_a_short_one() {
        let mut l = Limiter::new("commands refused", 1.0);
        for i in 0..7 {
            said(&mut l, 0.1 + i as f64 * 0.01, "a", "x");
        }
        // The next warning comes after the window, with no tick between: summary first.
        assert_eq!(said(&mut l, 2.0, "b", "y"), ["7 commands refused in the last second, 5 shown: 7 a", "y"]);
        for _ in 0..6 {
            said(&mut l, 2.25, "b", "y");
        }
        let mut out = Vec::new();
        l.flush(2.5, &mut |s: &str| out.push(s.to_string()));
        assert_eq!(out, ["7 commands refused in the last 0.50 s, 5 shown: 7 b"]);
        assert_eq!(l.summarised(), 2 + 2);
    }

    #[test]
    fn many_groups_are_lumped_together() {
        let mut l = Limiter::new("commands refused", 1.0);
        for g in 0..40 {
            said(&mut l, 0.0, &format!("g{g}"), "x");
        }
        let mut out = Vec::new();
        l.tick(1.0, &mut |s: &str| out.push(s.to_string()));
        assert!(out[0].ends_with("1 g15, 24 others"), "{}", out[0]);
    }

    /// A writer that never returns (a pipe nobody reads), after it took `lines` lines.
    struct Stuck(Arc<std::sync::Mutex<Vec<u8>>>, usize);

    impl Write for Stuck {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let mut held = self.0.lock().unwrap();
            if held.iter().filter(|&&b| b == b'\n').count() >= self.1 {
                drop(held);
                loop {
                    std::thread::park();
                }
            }
            held.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_writer_that_blocks_for_ever_never_blocks_the_sender_and_the_lost_lines_are_counted() {
        let got = Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut q = LineQueue::spawn(Stuck(got.clone(), 3));
        let start = Instant::now();
        for i in 0..10_000 {
            q.send(format!("line {i}"));
        }
        let sending = start.elapsed();
        assert!(sending < Duration::from_millis(500), "{sending:?}");
        let lost = q.finish(Duration::from_millis(50));
        assert!(start.elapsed() < Duration::from_secs(2));
        // Three lines written; the rest dropped, queued or stuck in the blocked write.
        let written = String::from_utf8(got.lock().unwrap().clone()).unwrap();
        assert_eq!(written, "line 0\nline 1\nline 2\n");
        assert_eq!(lost, 10_000 - 3);
    }

    #[test]
    fn a_writer_that_keeps_up_gets_every_line() {
        let got = Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut q = LineQueue::spawn(Stuck(got.clone(), usize::MAX));
        for i in 0..20 {
            q.send(format!("line {i}"));
        }
        assert_eq!(q.finish(Duration::from_secs(5)), 0);
        assert_eq!(got.lock().unwrap().iter().filter(|&&b| b == b'\n').count(), 20);
    }

    #[test]
    fn warnings_go_to_both_sinks_rate_limited_and_a_sink_that_refuses_is_counted() {
        let got = Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut w = Warnings::new("commands refused", Stuck(got.clone(), usize::MAX));
        let mut rosout = Vec::new();
        for i in 0..100 {
            w.warn("t (r)", &format!("t: command refused: {i}"), |l: &str| {
                rosout.push(l.to_string());
                i % 2 == 0
            });
        }
        w.tick(|_: &str| true); // within the first second (the clock is real here): nothing
        let counts = w.finish(|l: &str| {
            rosout.push(l.to_string());
            true
        });
        assert_eq!(rosout.len(), 6, "{rosout:?}");
        assert!(rosout[5].starts_with("100 commands refused in the last "), "{}", rosout[5]);
        assert_eq!(counts, WarningCounts { summarised: 95, stderr_dropped: 0, rosout_dropped: 2 });
        let text = String::from_utf8(got.lock().unwrap().clone()).unwrap();
        assert!(text.starts_with("warning: t: command refused: 0\n"), "{text}");
        assert_eq!(text.lines().count(), 6);
    }
}
