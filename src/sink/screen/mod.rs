//! The live screen: on a terminal, `dronewatt monitor` and `dronewatt replay` draw a full
//! screen (ratatui on crossterm, in the alternate screen) instead of the line view
//! ([`super::terminal`], which `--plain`, and any stdout that is not a terminal, keep).
//!
//! ```text
//!  dronewatt   vehicle 1  t 123.4 s   q quit
//! ┌ Power ─────────┐┌ Forecast ──────┐┌ Remaining energy ─────┐┌ Time to empty ┐
//! │measured 512 W  ││498.1 W         ││21.3 Wh (38%)          ││2 min 31 s     │
//! │lstm 480~505 W ◀││on lstm (adapted)││from: resting voltage ││…              │
//! └────────────────┘└────────────────┘└───────────────────────┘└───────────────┘
//! ┌ Margins ───────┐┌ Pack ─────────────────┐┌ Link ─────────────────────────┐
//! ┌ Power, last 5 min (W): measured, the forecast model's estimate, the forecast ┐
//! ┌ Alerts: time, rule, severity, message, newest first ┐┌ Vehicles (fleet mode) ┐
//! ```
//!
//! The tiles show the selected vehicle: with several on the link a vehicle list appears,
//! and ↑/↓ pick one. `q` or Ctrl-C ends the run (the same stop as SIGINT: the chain drains
//! and the sinks flush); SIGINT/SIGTERM from outside, and the end of a replay, end it too.
//!
//! The terminal is always given back (raw mode off, alternate screen left, cursor shown):
//! by `Screen`'s `Drop` when the screen ends or its task is dropped, and by a panic hook
//! before any panic message is printed. While the screen is up, stderr (the log) goes into
//! a pipe: its newest line shows at the bottom of the screen, and every line is written
//! to the real stderr once the screen is gone, so no log line scribbles over the screen
//! and none is lost. After the screen: the last status line and the run's counters, as the
//! line view ends.

mod state;
mod tiles;
mod widgets;

pub use state::ScreenState;
pub use widgets::{draw, LinkView};

use std::io::{BufRead, Stdout};
use std::os::fd::FromRawFd;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{mpsc as std_mpsc, Arc, Once};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use crossterm::terminal::{
    disable_raw_mode, enable_raw_mode, EnterAlternateScreen, LeaveAlternateScreen,
};
use ratatui::backend::CrosstermBackend;
use ratatui::Terminal;
use tokio::sync::mpsc;

use super::terminal;
use super::ReportRx;
use crate::report::status::ChainStatus;

/// How often the screen is drawn.
const FRAME: Duration = Duration::from_millis(250);

/// Whether the terminal is in the screen's state (raw, alternate screen, cursor hidden).
static TERMINAL_TAKEN: AtomicBool = AtomicBool::new(false);
/// The real stderr, saved while stderr goes into the screen's pipe (-1: not redirected).
static SAVED_STDERR: AtomicI32 = AtomicI32::new(-1);

/// Give the terminal back: raw mode off, alternate screen left, cursor shown. Once, however
/// often it is called (the guard's drop and the panic hook both call it).
fn restore_terminal() {
    if TERMINAL_TAKEN.swap(false, Ordering::SeqCst) {
        let _ = disable_raw_mode();
        let _ = crossterm::execute!(
            std::io::stdout(),
            LeaveAlternateScreen,
            crossterm::cursor::Show
        );
    }
}

/// Point fd 2 back at the real stderr (the pipe's write end closes: its reader ends).
fn restore_stderr() {
    let fd = SAVED_STDERR.swap(-1, Ordering::SeqCst);
    if fd >= 0 {
        // SAFETY: `fd` is the duplicate of fd 2 this module made and nothing else closes.
        unsafe {
            libc::dup2(fd, 2);
            libc::close(fd);
        }
    }
}

/// A panic anywhere gives the terminal and stderr back first, so its message is readable
/// and the shell is usable.
fn install_panic_hook() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            restore_terminal();
            restore_stderr();
            previous(info);
        }));
    });
}

/// Stderr into a pipe while the screen is up; a thread reads it line by line.
struct StderrCapture {
    lines: std_mpsc::Receiver<String>,
    reader: Option<JoinHandle<()>>,
}

impl StderrCapture {
    fn start() -> std::io::Result<Self> {
        let mut fds = [0; 2];
        // SAFETY: plain POSIX calls on descriptors this function owns; fd 2 is saved
        // before it is replaced, and every failure path closes what was opened.
        let read_end = unsafe {
            if libc::pipe(fds.as_mut_ptr()) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            let saved = libc::dup(2);
            if saved < 0 || libc::dup2(fds[1], 2) < 0 {
                let e = std::io::Error::last_os_error();
                if saved >= 0 {
                    libc::close(saved);
                }
                libc::close(fds[0]);
                libc::close(fds[1]);
                return Err(e);
            }
            libc::close(fds[1]);
            SAVED_STDERR.store(saved, Ordering::SeqCst);
            std::fs::File::from_raw_fd(fds[0])
        };
        let (tx, lines) = std_mpsc::channel();
        let reader = std::thread::Builder::new()
            .name("screen-log".into())
            .spawn(move || {
                for line in std::io::BufReader::new(read_end).lines() {
                    let Ok(line) = line else { break };
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            })?;
        Ok(Self {
            lines,
            reader: Some(reader),
        })
    }

    /// Stderr back, and every line that had not been taken yet.
    fn finish(&mut self) -> Vec<String> {
        restore_stderr();
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
        self.lines.try_iter().collect()
    }
}

/// What a key asks of the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    Quit,
    Move(isize),
    Redraw,
    /// Any other key (it leaves a replay's held final state).
    Other,
}

/// The terminal, taken: raw mode, the alternate screen, cursor hidden, stderr in a pipe,
/// keys read on a thread of their own. Dropping it gives everything back.
struct Screen {
    terminal: Terminal<CrosstermBackend<Stdout>>,
    keys: mpsc::UnboundedReceiver<Key>,
    key_stop: Arc<AtomicBool>,
    key_thread: Option<JoinHandle<()>>,
    log: Option<StderrCapture>,
}

impl Screen {
    fn enter() -> std::io::Result<Self> {
        install_panic_hook();
        let result = Self::take();
        if result.is_err() {
            restore_terminal();
            restore_stderr();
        }
        result
    }

    fn take() -> std::io::Result<Self> {
        enable_raw_mode()?;
        TERMINAL_TAKEN.store(true, Ordering::SeqCst);
        crossterm::execute!(
            std::io::stdout(),
            EnterAlternateScreen,
            crossterm::cursor::Hide
        )?;
        let mut terminal = Terminal::new(CrosstermBackend::new(std::io::stdout()))?;
        terminal.clear()?;
        let (tx, keys) = mpsc::unbounded_channel();
        let key_stop = Arc::new(AtomicBool::new(false));
        let stop = key_stop.clone();
        let key_thread = std::thread::Builder::new()
            .name("screen-keys".into())
            .spawn(move || read_keys(&tx, &stop))?;
        // Last, so an error before this point still reaches the real stderr.
        let log = StderrCapture::start()
            .map_err(|e| tracing::warn!("the log stays on stderr under the screen: {e}"))
            .ok();
        Ok(Self {
            terminal,
            keys,
            key_stop,
            key_thread: Some(key_thread),
            log,
        })
    }

    /// Give the terminal and stderr back; the log lines not shown yet.
    fn leave(&mut self) -> Vec<String> {
        self.key_stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.key_thread.take() {
            let _ = t.join();
        }
        restore_terminal();
        self.log.as_mut().map(|l| l.finish()).unwrap_or_default()
    }
}

impl Drop for Screen {
    fn drop(&mut self) {
        for line in self.leave() {
            eprintln!("{line}");
        }
    }
}

/// Read keys until `stop` (polling, so the thread ends within 100 ms of being told).
fn read_keys(tx: &mpsc::UnboundedSender<Key>, stop: &AtomicBool) {
    while !stop.load(Ordering::SeqCst) {
        match event::poll(Duration::from_millis(100)) {
            Ok(false) => continue,
            Ok(true) => {}
            Err(_) => return,
        }
        let key = match event::read() {
            Ok(Event::Key(k)) if k.kind != KeyEventKind::Release => match k.code {
                KeyCode::Char('q' | 'Q') | KeyCode::Esc => Key::Quit,
                KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => Key::Quit,
                KeyCode::Up | KeyCode::Char('k') => Key::Move(-1),
                KeyCode::Down | KeyCode::Char('j') => Key::Move(1),
                KeyCode::PageUp | KeyCode::Home => Key::Move(-1000),
                KeyCode::PageDown | KeyCode::End => Key::Move(1000),
                _ => Key::Other,
            },
            Ok(Event::Resize(..)) => Key::Redraw,
            Ok(_) => continue,
            Err(_) => return,
        };
        if tx.send(key).is_err() {
            return;
        }
    }
}

/// Strip ANSI escape sequences (the log is coloured when stderr was a terminal).
fn plain_text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        if c == '\x1b' {
            if chars.next() == Some('[') {
                for c in chars.by_ref() {
                    if ('@'..='~').contains(&c) {
                        break;
                    }
                }
            }
        } else if !c.is_control() {
            out.push(c);
        }
    }
    out
}

/// Run the screen until the report channel closes, a key quits, or the run is stopped.
/// When the reports end on their own (a replay's last), the final state stays on the
/// screen until a key is pressed (or the run is stopped); the screen is only drawn on a
/// terminal, so nothing waits where no one can press one. When the terminal cannot be
/// taken, the line view runs instead. `detail`: every model's estimate beside the chart.
pub async fn run(mut rx: ReportRx, status: ChainStatus, detail: bool) -> anyhow::Result<()> {
    let mut screen = match Screen::enter() {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("no screen ({e}): the line view instead");
            return terminal::run(rx, status, detail).await;
        }
    };
    let ChainStatus {
        stats,
        shutdown,
        latency,
        ..
    } = status;
    let mut state = ScreenState::default();
    let mut shown_logs = Vec::new();
    let mut tick = tokio::time::interval(FRAME);
    let mut last = (Instant::now(), stats.frames_ok.load(Ordering::Relaxed));
    let mut keys_open = true;
    let mut failed = None;
    loop {
        let mut redraw = false;
        tokio::select! {
            r = rx.next(), if !state.ended => match r {
                Some(r) => state.push(r),
                // Held until a key: only while keys can come.
                None if keys_open && !shutdown.is_cancelled() => {
                    state.ended = true;
                    redraw = true;
                }
                None => break,
            },
            k = screen.keys.recv(), if keys_open => match k {
                Some(Key::Quit) => {
                    shutdown.cancel();
                    break;
                }
                Some(_) if state.ended => break,
                Some(Key::Move(by)) => {
                    state.move_selection(by);
                    redraw = true;
                }
                Some(Key::Redraw) => redraw = true,
                Some(Key::Other) => {}
                None if state.ended => break,
                None => keys_open = false,
            },
            _ = shutdown.cancelled() => break,
            _ = tick.tick() => {
                let dt = last.0.elapsed().as_secs_f64();
                if dt >= 1.0 {
                    let ok = stats.frames_ok.load(Ordering::Relaxed);
                    state.rate = ok.saturating_sub(last.1) as f64 / dt;
                    last = (Instant::now(), ok);
                }
                if let Some(log) = &screen.log {
                    for line in log.lines.try_iter() {
                        state.log_line(plain_text(&line));
                        shown_logs.push(line);
                    }
                }
                redraw = true;
            }
        }
        if redraw {
            let link = LinkView {
                stats: stats.snapshot(),
                silent: stats.silent.load(Ordering::Relaxed),
                missed: rx.missed(),
            };
            if let Err(e) = screen.terminal.draw(|f| draw(f, &state, &link, detail)) {
                failed = Some(e);
                shutdown.cancel();
                break;
            }
        }
    }
    let rest = screen.leave();
    drop(screen);
    for line in shown_logs.iter().chain(&rest) {
        eprintln!("{line}");
    }
    if let Some(e) = failed {
        tracing::warn!("the screen could not draw ({e}): the run was stopped");
    }
    // After a quit the chain drains: take what it still sends (its alerts too).
    while let Some(r) = rx.next().await {
        state.push(r);
    }
    let rate = state.rate;
    if state.is_fleet() {
        let fleet = state
            .vehicles
            .iter()
            .map(|(&id, v)| (id, (v.report.clone(), v.active.clone())))
            .collect();
        eprintln!("{}", terminal::fleet_view(&fleet, &stats, rate, false));
    } else if let Some(v) = state.selected() {
        eprintln!(
            "{}",
            terminal::status_line(Some((&*v.report, &v.active)), &stats, rate, false, detail)
        );
    }
    terminal::print_summary(&stats, rx.missed(), "the screen", &latency);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::backend::TestBackend;

    #[test]
    fn plain_text_drops_colour() {
        assert_eq!(
            plain_text("\x1b[2m2025\x1b[0m \x1b[33m WARN\x1b[0m x"),
            "2025  WARN x"
        );
    }

    #[test]
    fn an_empty_screen_draws_its_tiles() {
        let mut t = Terminal::new(TestBackend::new(120, 40)).unwrap();
        let state = ScreenState::default();
        let link = LinkView {
            stats: Default::default(),
            silent: true,
            missed: 0,
        };
        t.draw(|f| draw(f, &state, &link, false)).unwrap();
        let text: String = t
            .backend()
            .buffer()
            .content
            .iter()
            .map(|c| c.symbol())
            .collect();
        for title in [
            "Time left",
            "State of charge",
            "Voltage",
            "Margins",
            "Power",
            "Pack model",
            "Link",
            "Alerts",
            "SILENT",
            "waiting for the first window",
        ] {
            assert!(text.contains(title), "{title} missing");
        }
    }
}
