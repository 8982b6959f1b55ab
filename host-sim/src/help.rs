//! The end of every command's `--help`: examples that run from the repository's
//! root on its shipped files (`examples/`, `tests/scenarios/`), and the documents
//! that tell the whole. One layout for all; `cli.rs`'s tests walk the command tree
//! and check that every command has both, that every example parses as the
//! command it shows, and that every file and document it names exists.

/// The epilogue: `examples` (command lines, `host-sim` first), then `notes`
/// (paragraphs, may be empty), then the documents `docs`.
pub fn epilogue(examples: &[&str], notes: &[String], docs: &[&str]) -> String {
    let mut text = String::from("Examples:\n");
    for e in examples {
        text.push_str(&format!("  {e}\n"));
    }
    for n in notes {
        text.push_str(&format!("\n{n}\n"));
    }
    text.push_str(&format!("\nDocumentation: {}", docs.join(", ")));
    text
}
