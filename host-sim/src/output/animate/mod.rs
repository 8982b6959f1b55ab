//! `--animate FILE.html` (`run`, `scenario`): the run as one self-contained HTML page
//! that plays it: every body's outline, the feet and the floor, the rotors'
//! eccentrics at their angles, the contact forces as arrows in their friction cones,
//! the impacts as they happen, the phase offset and the rotor speeds; controls for
//! play and pause, the time, the playback rate and a magnification of the
//! displacements; the main traces below with a cursor. docs/cli-run.md describes
//! the page and its script interface (`window.vibro`).
//!
//! - [`frames`]: the trace decimated to a frame every 2 ms, the impacts and the
//!   controller's events, as JSON columns;
//! - [`scene`]: what does not move: outlines, feet, rotors, joints, the fundament.
//!
//! The page is `page.html` (markup and style) with `page.js` (the player, vanilla
//! JavaScript drawing on `<canvas>`) and the data inlined: nothing is loaded from
//! anywhere, no font, no script, no image. The same run gives the same bytes.

pub mod frames;
pub mod scene;

use frames::{Frames, FRAME_STEP};

use crate::event::EventRow;
use crate::machine::Machine;
use crate::output::svg::escape;
use crate::simulation::trace::TraceRow;
use crate::simulation::Observer;

/// The longest run an animation holds, s of simulated time: 300 000 frames, about
/// 40 MB for the reference machine (62 kB per simulated second, measured: 3.7 MB
/// for 60 s travelling; a browser still opens it).
pub const MAX_SECONDS: f64 = 600.0;

/// The page's markup and style, with `{{TITLE}}`, `{{DATA}}` and `{{SCRIPT}}`.
const TEMPLATE: &str = include_str!("page.html");

/// The player.
const SCRIPT: &str = include_str!("page.js");

/// The help of `--animate` (`run`, `scenario`), its limit from [`MAX_SECONDS`].
pub fn option_help() -> String {
    format!(
        "Write the run as an HTML page that plays it (self-contained; runs of at most {} s)",
        crate::numbers::sig(MAX_SECONDS)
    )
}

/// A refusal if a run of `t_end` s is longer than an animation holds; `origin`
/// names where `t_end` came from (`--t-end`, `simulation.t_end`, a scenario key).
pub fn check_duration(t_end: f64, origin: &str) -> Option<String> {
    (t_end > MAX_SECONDS).then(|| {
        format!(
            "--animate: {origin} {t_end}: an animation holds at most {MAX_SECONDS} s of simulated time (a frame every {} ms, about 40 MB at {MAX_SECONDS} s for a machine on two feet): animate a shorter run",
            FRAME_STEP * 1e3
        )
    })
}

/// An observer that films the run (when asked) and passes everything on to
/// `inner`, which decides whether the run goes on.
pub struct Film<'o> {
    /// The frames, if the run is animated.
    pub frames: Option<Frames>,
    /// The observer filmed alongside.
    pub inner: &'o mut dyn Observer,
}

impl Observer for Film<'_> {
    fn row(&mut self, row: &TraceRow) {
        if let Some(f) = &mut self.frames {
            f.row(row);
        }
        self.inner.row(row);
    }

    fn events(&mut self, batch: &[EventRow]) {
        if let Some(f) = &mut self.frames {
            f.events(batch);
        }
        self.inner.events(batch);
    }

    fn go_on(&mut self, t: f64) -> bool {
        self.inner.go_on(t)
    }

    fn stop_flag(&self) -> Option<&'static std::sync::atomic::AtomicUsize> {
        self.inner.stop_flag()
    }
}

/// The page for the run of `machine` filmed in `frames`, titled `title`.
pub fn page(title: &str, machine: &Machine, frames: &mut Frames) -> String {
    let columns = frames.columns_json();
    let data = format!(
        r#"{{"title":{},"frame_step":{FRAME_STEP},"frames":{},"scene":{},"columns":{columns},"events":{}}}"#,
        serde_json::Value::from(title),
        frames.count(),
        scene::scene(machine),
        frames.events_json(),
    );
    // Inside <script> only `</script` ends the element: JSON has `<` in strings
    // only, where `\u003c` means the same.
    let data = data.replace('<', "\\u003c");
    fill(
        TEMPLATE,
        &[
            ("{{TITLE}}", &escape(title)),
            ("{{DATA}}", &data),
            ("{{SCRIPT}}", SCRIPT),
        ],
    )
}

/// `template` with each marker replaced by its text, the template read once (a
/// marker inside a replacement stays as it is).
fn fill(template: &str, marks: &[(&str, &str)]) -> String {
    let mut out =
        String::with_capacity(template.len() + marks.iter().map(|m| m.1.len()).sum::<usize>());
    let mut rest = template;
    while let Some((at, (mark, text))) = marks
        .iter()
        .filter_map(|m| rest.find(m.0).map(|at| (at, m)))
        .min_by_key(|(at, _)| *at)
    {
        out.push_str(&rest[..at]);
        out.push_str(text);
        rest = &rest[at + mark.len()..];
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_reads_the_template_once() {
        assert_eq!(
            fill("<{{A}}|{{B}}>", &[("{{A}}", "{{B}}"), ("{{B}}", "b")]),
            "<{{B}}|b>"
        );
    }
}
