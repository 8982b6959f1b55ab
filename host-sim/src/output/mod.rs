//! What commands write: whole files, CSV, SVG pieces, text for people.
//!
//! - [`animate`]: a run as a self-contained HTML page that plays it;
//! - [`file`](mod@file): a file written whole or not at all;
//! - [`machine_edit`]: a machine file with numbers changed, its comments kept;
//! - [`csv`]: the trace and the events as CSV;
//! - [`progress`]: a long command's progress on stderr (a bar, or lines off a
//!   terminal);
//! - [`svg`]: the SVG figures' common pieces;
//! - [`temporary`]: where a file waits until its set is committed;
//! - [`text`]: aligned tables for people (their numbers written by
//!   [`crate::numbers`]).

pub mod animate;
pub mod csv;
pub mod file;
pub mod machine_edit;
pub mod progress;
pub mod svg;
pub mod temporary;
pub mod text;
