//! A small, tolerant reader for the YAML subset of camera calibration files, and a float
//! formatter that round-trips exactly.
//!
//! Supported: `%YAML` directives, `---` / `...` markers, `#` comments, block mappings by
//! indentation, local and global tags (`!!opencv-matrix`) which are ignored, plain, single- and
//! double-quoted scalars, flow sequences `[a, b, c]` spanning several lines, and block sequences
//! of scalars (`- a`). Anything else is reported with its line number.

use crate::error::{Result, VisionError};

/// A parsed value.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Node {
    /// A scalar, quotes removed.
    Scalar(String),
    /// A sequence of scalars.
    Seq(Vec<String>),
    /// A mapping, in file order.
    Map(Vec<Entry>),
}

/// One `key: value` pair.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Entry {
    /// The key, quotes removed.
    pub key: String,
    /// 1-based line of the key.
    pub line: usize,
    /// The value.
    pub value: Node,
}

struct Line<'a> {
    number: usize,
    indent: usize,
    text: &'a str,
}

fn parse_error(source_name: &str, line: usize, message: impl Into<String>) -> VisionError {
    VisionError::Parse { source_name: source_name.to_string(), line, message: message.into() }
}

/// Removes a trailing comment (a `#` at the start or after whitespace, outside quotes).
fn strip_comment(s: &str) -> &str {
    let mut quote: Option<char> = None;
    let mut prev_space = true;
    for (i, ch) in s.char_indices() {
        match quote {
            Some(q) if ch == q => quote = None,
            Some(_) => {}
            None => {
                if ch == '#' && prev_space {
                    return &s[..i];
                }
                if ch == '"' || ch == '\'' {
                    quote = Some(ch);
                }
            }
        }
        prev_space = ch.is_whitespace();
    }
    s
}

/// Removes matching surrounding quotes.
fn unquote(s: &str) -> String {
    let s = s.trim();
    if s.len() >= 2 && ((s.starts_with('"') && s.ends_with('"')) || (s.starts_with('\'') && s.ends_with('\''))) {
        s[1..s.len() - 1].to_string()
    } else {
        s.to_string()
    }
}

/// Removes a leading tag (`!!opencv-matrix`, `!foo`) from a value.
fn strip_tag(s: &str) -> &str {
    let s = s.trim();
    if s.starts_with('!') {
        match s.find(char::is_whitespace) {
            Some(i) => s[i..].trim(),
            None => "",
        }
    } else {
        s
    }
}

/// Splits `key: value` at the first `:` followed by whitespace or end of line, outside quotes.
fn split_key(s: &str) -> Option<(&str, &str)> {
    let bytes = s.as_bytes();
    let mut quote: Option<u8> = None;
    for i in 0..bytes.len() {
        let b = bytes[i];
        match quote {
            Some(q) if b == q => quote = None,
            Some(_) => {}
            None => {
                if b == b'"' || b == b'\'' {
                    quote = Some(b);
                } else if b == b':' && (i + 1 == bytes.len() || bytes[i + 1] == b' ') {
                    return Some((&s[..i], &s[i + 1..]));
                }
            }
        }
    }
    None
}

/// Parses a document whose top level is a mapping.
pub(crate) fn parse(text: &str, source_name: &str) -> Result<Vec<Entry>> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let number = i + 1;
        let no_comment = strip_comment(raw);
        let trimmed = no_comment.trim_end();
        if trimmed.trim().is_empty() {
            continue;
        }
        if trimmed.starts_with('%') || trimmed == "---" || trimmed == "..." {
            continue;
        }
        let body = trimmed.trim_start_matches(' ');
        if body.starts_with('\t') {
            return Err(parse_error(source_name, number, "tab used for indentation; YAML needs spaces"));
        }
        lines.push(Line { number, indent: trimmed.len() - body.len(), text: body });
    }
    if lines.is_empty() {
        return Err(parse_error(source_name, 0, "empty document"));
    }
    let mut idx = 0;
    let indent = lines[0].indent;
    let map = parse_map(&lines, &mut idx, indent, source_name)?;
    if idx < lines.len() {
        return Err(parse_error(source_name, lines[idx].number, "unexpected indentation"));
    }
    Ok(map)
}

fn parse_map(lines: &[Line<'_>], idx: &mut usize, indent: usize, source_name: &str) -> Result<Vec<Entry>> {
    let mut out = Vec::new();
    while *idx < lines.len() {
        let line = &lines[*idx];
        if line.indent < indent {
            break;
        }
        if line.indent > indent {
            return Err(parse_error(source_name, line.number, "unexpected indentation"));
        }
        let (key, rest) = split_key(line.text).ok_or_else(|| {
            parse_error(source_name, line.number, format!("expected 'key: value', found '{}'", line.text))
        })?;
        let key = unquote(key);
        let number = line.number;
        *idx += 1;
        let rest = strip_tag(rest);
        let value = if rest.starts_with('[') {
            parse_flow_seq(lines, idx, rest, number, source_name)?
        } else if rest.starts_with('{') {
            return Err(parse_error(
                source_name,
                number,
                "flow mappings '{...}' are not supported; write a block mapping",
            ));
        } else if !rest.is_empty() {
            Node::Scalar(unquote(rest))
        } else if *idx < lines.len() && lines[*idx].indent > indent {
            let child_indent = lines[*idx].indent;
            if lines[*idx].text.starts_with("- ") || lines[*idx].text == "-" {
                parse_block_seq(lines, idx, child_indent, source_name)?
            } else {
                Node::Map(parse_map(lines, idx, child_indent, source_name)?)
            }
        } else if *idx < lines.len()
            && lines[*idx].indent == indent
            && (lines[*idx].text.starts_with("- ") || lines[*idx].text == "-")
        {
            // A block sequence may sit at the key's own indentation.
            parse_block_seq(lines, idx, indent, source_name)?
        } else {
            Node::Scalar(String::new())
        };
        out.push(Entry { key, line: number, value });
    }
    Ok(out)
}

fn parse_block_seq(lines: &[Line<'_>], idx: &mut usize, indent: usize, source_name: &str) -> Result<Node> {
    let mut items = Vec::new();
    while *idx < lines.len() && lines[*idx].indent == indent {
        let t = lines[*idx].text;
        let Some(item) = t.strip_prefix('-') else {
            break;
        };
        let item = item.trim();
        if item.starts_with('[') || item.starts_with('{') || split_key(item).is_some() {
            return Err(parse_error(source_name, lines[*idx].number, "only sequences of scalars are supported"));
        }
        items.push(unquote(item));
        *idx += 1;
    }
    Ok(Node::Seq(items))
}

fn parse_flow_seq(lines: &[Line<'_>], idx: &mut usize, first: &str, number: usize, source_name: &str) -> Result<Node> {
    let mut text = first.to_string();
    while !text.contains(']') {
        if *idx >= lines.len() {
            return Err(parse_error(source_name, number, "flow sequence '[' is never closed"));
        }
        text.push(' ');
        text.push_str(lines[*idx].text);
        *idx += 1;
    }
    let close = text.rfind(']').unwrap_or(text.len());
    if !text[close + 1..].trim().is_empty() {
        return Err(parse_error(source_name, number, "unexpected text after ']'"));
    }
    let inner = &text[1..close];
    if inner.contains('[') || inner.contains('{') {
        return Err(parse_error(source_name, number, "nested flow collections are not supported"));
    }
    let items = inner.split(',').map(unquote).filter(|s| !s.is_empty()).collect();
    Ok(Node::Seq(items))
}

/// Formats a finite `f64` so that parsing it back gives the same bits, in a form every YAML
/// reader takes for a float: plain decimals for `1e-4 <= |v| < 1e16`, otherwise scientific with
/// a signed two-digit exponent (`1.5e-07`); always with a decimal point.
pub(crate) fn fmt_f64(v: f64) -> String {
    if v == 0.0 {
        return if v.is_sign_negative() { "-0.0" } else { "0.0" }.to_string();
    }
    let a = v.abs();
    if (1e-4..1e16).contains(&a) {
        let s = format!("{v}");
        if s.contains('.') {
            s
        } else {
            s + ".0"
        }
    } else {
        let s = format!("{v:e}");
        match s.split_once('e') {
            Some((m, e)) => {
                let m = if m.contains('.') { m.to_string() } else { format!("{m}.0") };
                let e: i32 = e.parse().unwrap_or(0);
                format!("{m}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
            }
            None => s,
        }
    }
}

/// Parses a YAML float (plain decimal or scientific; OpenCV's `0.` form included).
pub(crate) fn parse_f64(s: &str) -> Option<f64> {
    let v: f64 = s.trim().parse().ok()?;
    v.is_finite().then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmt_f64_round_trips_exactly() {
        let values = [
            535.9157,
            -0.26637,
            1.0,
            0.1 + 0.2,
            1e-20,
            -3.3e-5,
            6.02214076e23,
            f64::MIN_POSITIVE,
            f64::MAX,
            1.0 / 3.0,
            -0.0,
            123456789012345.67,
        ];
        for v in values {
            let s = fmt_f64(v);
            assert!(s.contains('.'), "{s}");
            let back = parse_f64(&s).unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v} -> {s}");
        }
        assert_eq!(parse_f64("0."), Some(0.0));
        assert_eq!(parse_f64("5.3591573396163199e+02"), Some(535.915_733_961_632));
        assert_eq!(parse_f64(".nan"), None);
    }

    #[test]
    fn parses_nested_maps_flow_sequences_and_comments() {
        let text = "%YAML:1.0\n---\n# comment\nname: \"left # not a comment\"\nm: !!opencv-matrix\n   rows: 2\n   cols: 1\n   data: [ 1.,\n       2.5e+00 ]  # trailing\nseq:\n  - a\n  - 'b'\n";
        let doc = parse(text, "<test>").unwrap();
        assert_eq!(doc[0].key, "name");
        assert_eq!(doc[0].value, Node::Scalar("left # not a comment".into()));
        match &doc[1].value {
            Node::Map(m) => {
                assert_eq!(m[0].value, Node::Scalar("2".into()));
                assert_eq!(m[2].value, Node::Seq(vec!["1.".into(), "2.5e+00".into()]));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(doc[2].value, Node::Seq(vec!["a".into(), "b".into()]));
        let err = parse("a: 1\n   b: 2\n", "<test>").unwrap_err();
        assert!(err.to_string().contains(":2:"), "{err}");
    }
}
