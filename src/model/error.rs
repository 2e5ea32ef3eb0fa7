//! Errors in model files, located by file, line, column and field.

use std::fmt;
use std::ops::Range;

/// A problem in a model file (or its `--set` overrides).
///
/// Displays as `FILE:LINE:COL: field `path`: message`, leaving out the parts that are
/// unknown (a file that cannot be read has no line; an override has no position).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", render(self))]
pub struct ModelError {
    pub file: String,
    /// 1-based line and column (in characters) of the offending text
    pub line: Option<usize>,
    pub column: Option<usize>,
    /// dotted path of the field, `beams[0].elements` (arrays indexed from 0, file order)
    pub field: Option<String>,
    pub message: String,
}

fn render(e: &ModelError) -> String {
    let mut s = e.file.clone();
    if let Some(l) = e.line {
        s += &format!(":{l}");
        if let Some(c) = e.column {
            s += &format!(":{c}");
        }
    }
    s += ": ";
    if let Some(f) = &e.field {
        s += &format!("field `{}`: ", elide_long_words(f));
    }
    s + &elide_long_words(&e.message)
}

/// Longest run of non-blank characters a message shows whole.
const LONGEST_WORD: usize = 200;

/// `text` with every run of non-blank characters longer than [`LONGEST_WORD`] cut to its
/// head and its length: a name or key of megabytes (an unknown key, a mistyped reference)
/// made a message of megabytes, twice as large where the name appears twice.
pub fn elide_long_words(text: &str) -> String {
    if text.len() <= LONGEST_WORD {
        return text.to_string();
    }
    let mut out = String::with_capacity(text.len().min(4 * LONGEST_WORD));
    let mut word = String::new();
    let mut count = 0usize;
    let flush = |out: &mut String, word: &mut String, count: &mut usize| {
        out.push_str(word);
        if *count > LONGEST_WORD {
            out.push_str(&format!("… ({count} characters)"));
        }
        word.clear();
        *count = 0;
    };
    for c in text.chars() {
        if c.is_whitespace() {
            flush(&mut out, &mut word, &mut count);
            out.push(c);
        } else {
            count += 1;
            if count <= LONGEST_WORD {
                word.push(c);
            }
        }
    }
    flush(&mut out, &mut word, &mut count);
    out
}

impl ModelError {
    /// An error at byte offset range `span` of `text`.
    pub fn at(
        file: &str,
        text: &str,
        span: Range<usize>,
        field: impl Into<String>,
        message: impl fmt::Display,
    ) -> ModelError {
        // 0..0 is how spec::Spanned marks a value toml gave no position for
        let pos = (span != (0..0)).then(|| line_col(text, span.start));
        ModelError {
            file: file.to_string(),
            line: pos.map(|p| p.0),
            column: pos.map(|p| p.1),
            field: Some(field.into()),
            message: message.to_string(),
        }
    }

    /// An error that belongs to the whole file, not a place in it.
    pub fn file(file: &str, field: Option<String>, message: impl fmt::Display) -> ModelError {
        ModelError {
            file: file.to_string(),
            line: None,
            column: None,
            field,
            message: message.to_string(),
        }
    }
}

/// 1-based line and column (in characters) of a byte offset.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, text[line_start..offset].chars().count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_and_positions() {
        let text = "a = 1\nbé = 2\n";
        assert_eq!(line_col(text, 0), (1, 1));
        assert_eq!(line_col(text, 6), (2, 1));
        assert_eq!(line_col(text, 11), (2, 5), "columns count characters");
        let e = ModelError::at("m.toml", text, 6..8, "bé", "bad");
        assert_eq!(e.to_string(), "m.toml:2:1: field `bé`: bad");
        let e = ModelError::file("m.toml", None, "cannot read");
        assert_eq!(e.to_string(), "m.toml: cannot read");
    }

    /// A name of megabytes is cut in the message; words of ordinary length stay whole.
    #[test]
    fn a_huge_name_in_a_message_is_cut_to_its_head_and_length() {
        let name = "a".repeat(5_000_000);
        let e = ModelError::file(
            "m.toml",
            Some(format!("solver.{name}")),
            format!("unknown key `{name}` (keys: dt, t_end)"),
        );
        let text = e.to_string();
        assert!(text.len() < 1_000, "{} bytes", text.len());
        assert!(text.contains("(5000007 characters)"), "{text}");
        assert!(text.contains("(5000002 characters)"), "{text}");
        assert!(text.ends_with("(keys: dt, t_end)"), "{text}");
        let short = ModelError::file("m.toml", Some("solver.dtt".into()), "unknown key `dtt`");
        assert_eq!(
            short.to_string(),
            "m.toml: field `solver.dtt`: unknown key `dtt`"
        );
    }
}
