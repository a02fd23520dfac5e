//! Bounded echoes of client input in error messages: a name, a value or a whole message is cut
//! to a readable length with `…`, so a megabyte of input never comes back in an error.

use std::fmt;

/// Most characters of one piece of client input an error message repeats.
pub const ECHO_CHARS: usize = 80;

/// Most characters of an error message answered to a client.
pub const MESSAGE_CHARS: usize = 2000;

/// `text` for an error message: at most [`ECHO_CHARS`] characters, `…` when cut. Display
/// writes it as is, Debug quoted and escaped (`"abc…"`).
pub fn echo(text: &str) -> Echo<'_> {
    Echo(text)
}

/// Client input as shown in an error message; see [`echo`].
#[derive(Clone, Copy)]
pub struct Echo<'a>(&'a str);

impl Echo<'_> {
    /// The shown text: the input, or its first characters and `…`.
    fn shown(&self) -> std::borrow::Cow<'_, str> {
        match self.0.char_indices().nth(ECHO_CHARS) {
            None => self.0.into(),
            Some((end, _)) => format!("{}…", &self.0[..end]).into(),
        }
    }
}

impl fmt::Display for Echo<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.shown())
    }
}

impl fmt::Debug for Echo<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}", self.shown())
    }
}

/// A whole message bounded for a client: every run of more than [`ECHO_CHARS`] non-blank
/// characters is cut (keeping its closing quote or punctuation), and the message to
/// [`MESSAGE_CHARS`] characters.
pub fn bound_message(message: &str) -> String {
    let mut out = String::with_capacity(message.len().min(MESSAGE_CHARS * 4));
    let mut chars = 0;
    for piece in split_keeping_blanks(message) {
        let piece = if piece.chars().count() > ECHO_CHARS { shorten_token(piece) } else { piece.to_string() };
        for c in piece.chars() {
            if chars == MESSAGE_CHARS {
                out.push('…');
                return out;
            }
            out.push(c);
            chars += 1;
        }
    }
    out
}

/// `text` in runs of blank and of non-blank characters, in order.
fn split_keeping_blanks(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = text;
    std::iter::from_fn(move || {
        let first = rest.chars().next()?;
        let blank = first.is_whitespace();
        let end = rest.find(|c: char| c.is_whitespace() != blank).unwrap_or(rest.len());
        let (piece, tail) = rest.split_at(end);
        rest = tail;
        Some(piece)
    })
}

/// A long token cut to [`ECHO_CHARS`] characters and `…`, keeping up to three closing
/// punctuation characters (`` `abc…`, ``).
fn shorten_token(token: &str) -> String {
    let closing: String = {
        let tail: Vec<char> = token.chars().rev().take_while(|c| c.is_ascii_punctuation()).take(3).collect();
        tail.into_iter().rev().collect()
    };
    let mut out: String = token.chars().take(ECHO_CHARS).collect();
    out.push('…');
    out.push_str(&closing);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn echoes_are_cut_with_an_ellipsis() {
        assert_eq!(echo("winter").to_string(), "winter");
        assert_eq!(format!("{:?}", echo("say \"hi\"")), r#""say \"hi\"""#);
        let long = "ü".repeat(10_000);
        let shown = echo(&long).to_string();
        assert_eq!(shown.chars().count(), ECHO_CHARS + 1);
        assert!(shown.ends_with('…'));
        assert_eq!(format!("{:?}", echo(&long)), format!("\"{}\"", shown));
        assert_eq!(echo(&"a".repeat(ECHO_CHARS)).to_string(), "a".repeat(ECHO_CHARS));
    }

    #[test]
    fn messages_are_bounded_token_by_token_and_in_total() {
        assert_eq!(bound_message("unknown field `x`, expected `a`"), "unknown field `x`, expected `a`");
        let long = format!("unknown field `{}`, expected one of `a`", "p".repeat(1 << 20));
        let bounded = bound_message(&long);
        assert_eq!(bounded, format!("unknown field `{}…`, expected one of `a`", "p".repeat(ECHO_CHARS - 1)));
        let spaced = "ab ".repeat(1 << 20);
        let bounded = bound_message(&spaced);
        assert_eq!(bounded.chars().count(), MESSAGE_CHARS + 1);
        assert!(bounded.ends_with('…'));
    }
}
