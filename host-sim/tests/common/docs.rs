//! The fenced blocks of README.md and docs/*.md, which the documented-commands
//! tests run: the shell blocks as scripts, the `$ host-sim ...` transcripts of the
//! other blocks as commands whose output the docs show.

/// A fenced block of a document.
pub struct Block {
    /// Relative to the repository's root.
    pub file: String,
    /// The line of its opening fence, from 1.
    pub line: usize,
    /// Its info string (`sh`, `text`, `toml`, ...; empty when none).
    pub info: String,
    /// Its lines, the fence's indentation removed.
    pub text: String,
}

impl Block {
    /// `file:line` of its opening fence.
    pub fn place(&self) -> String {
        format!("{}:{}", self.file, self.line)
    }

    /// A shell block: what a reader pastes into a shell.
    pub fn is_shell(&self) -> bool {
        ["sh", "bash", "shell"].contains(&self.info.as_str())
    }
}

/// README.md, then docs/*.md in name order, relative to the repository's root.
pub fn documents() -> Vec<String> {
    let mut docs: Vec<String> = std::fs::read_dir(super::root().join("docs"))
        .expect("docs/")
        .map(|e| e.expect("an entry").file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    let mut files = vec!["README.md".to_string()];
    files.extend(docs);
    files
}

/// Every fenced block of README.md and docs/*.md, in file order.
pub fn blocks() -> Vec<Block> {
    let root = super::root();
    let mut blocks = Vec::new();
    for file in documents() {
        let text = std::fs::read_to_string(root.join(&file)).expect("a document");
        let mut open: Option<(usize, usize, String, String)> = None;
        for (i, line) in text.lines().enumerate() {
            let trimmed = line.trim_start();
            let indent = line.len() - trimmed.len();
            match open.take() {
                None => {
                    if let Some(info) = trimmed.strip_prefix("```") {
                        open = Some((i + 1, indent, info.trim().to_string(), String::new()));
                    }
                }
                Some((start, fence_indent, info, body)) => {
                    if trimmed == "```" {
                        blocks.push(Block {
                            file: file.clone(),
                            line: start,
                            info,
                            text: body,
                        });
                    } else {
                        let cut = indent.min(fence_indent);
                        let body = body + &line[cut..] + "\n";
                        open = Some((start, fence_indent, info, body));
                    }
                }
            }
        }
        assert!(open.is_none(), "{file}: a fenced block is not closed");
    }
    blocks
}
