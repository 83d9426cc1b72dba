//! A small delimited-table reader shared by the importers: one header row, `#` comment lines,
//! located cells and number parsing that names file, line and column in every error.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::{DatasetError, Location, Result};

/// The decimal separator a table uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Decimal {
    /// `1.5`
    Point,
    /// `1,5`
    Comma,
}

/// How a table is written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TableFormat {
    /// Field delimiter.
    pub delimiter: u8,
    /// Decimal separator of numbers.
    pub decimal: Decimal,
    /// Whether lines starting with `#` are comments.
    pub comments: bool,
}

impl TableFormat {
    /// Comma-separated, decimal point, `#` comments (the measurement CSV).
    pub const CSV: TableFormat = TableFormat { delimiter: b',', decimal: Decimal::Point, comments: true };

    /// Semicolon-separated, decimal comma, no comments (spreadsheet exports).
    pub const SEMICOLON_DECIMAL_COMMA: TableFormat =
        TableFormat { delimiter: b';', decimal: Decimal::Comma, comments: false };
}

/// One data row with the line it starts on.
#[derive(Clone, Debug)]
pub(crate) struct Row {
    /// 1-based line in the file.
    pub line: u64,
    /// Trimmed cells, exactly as many as the header has columns.
    pub cells: Vec<String>,
}

/// A parsed table.
#[derive(Clone, Debug)]
pub(crate) struct Table {
    /// Where it came from (for messages).
    pub file: PathBuf,
    /// 1-based line of the header.
    pub header_line: u64,
    /// Header names, trimmed.
    pub headers: Vec<String>,
    /// Data rows.
    pub rows: Vec<Row>,
    decimal: Decimal,
    index: HashMap<String, usize>,
}

/// Reads a whole file as UTF-8 text; an invalid byte is reported with its line.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|source| DatasetError::Io { path: path.to_path_buf(), source })?;
    match String::from_utf8(bytes) {
        Ok(s) => Ok(s),
        Err(e) => {
            let valid = e.utf8_error().valid_up_to();
            let line = 1 + e.as_bytes()[..valid].iter().filter(|b| **b == b'\n').count() as u64;
            Err(DatasetError::Invalid {
                location: Location::line(path, line),
                message: "the file is not valid UTF-8 text".to_string(),
            })
        }
    }
}

impl Table {
    /// Reads and parses a file.
    pub fn read(path: &Path, format: TableFormat, numeric: &dyn Fn(&str) -> bool) -> Result<Table> {
        let text = read_text(path)?;
        Table::parse(&text, path, format, numeric)
    }

    /// Parses text; `file` names it in messages. `numeric` tells which columns hold numbers (used
    /// to recognise a decimal comma that split a number into two cells).
    pub fn parse(text: &str, file: &Path, format: TableFormat, numeric: &dyn Fn(&str) -> bool) -> Result<Table> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        // Classic Mac line ends (CR alone): one line per CR.
        let unix;
        let text = if text.contains('\r') && !text.contains('\n') {
            unix = text.replace('\r', "\n");
            unix.as_str()
        } else {
            text
        };
        let mut records = split_records(text, file, format)?.into_iter();
        let (header_line, headers) = match records.next() {
            None => {
                return Err(DatasetError::Invalid {
                    location: Location::line(file, 1),
                    message: "the file has no header row".to_string(),
                })
            }
            Some(rec) => rec,
        };
        if let Some(e) = other_separator(&headers, file, header_line, format) {
            return Err(e);
        }
        let mut index = HashMap::new();
        for (i, h) in headers.iter().enumerate() {
            if h.is_empty() {
                return Err(DatasetError::Invalid {
                    location: Location::new(file, header_line, format!("field {}", i + 1)),
                    message: "empty column name in the header".to_string(),
                });
            }
            if index.insert(h.clone(), i).is_some() {
                return Err(DatasetError::Invalid {
                    location: Location::new(file, header_line, h.clone()),
                    message: "the column name occurs twice in the header".to_string(),
                });
            }
        }

        let mut rows = Vec::new();
        for (line, cells) in records {
            if cells.len() != headers.len() {
                return Err(field_count_error(file, line, &headers, &cells, format, numeric));
            }
            rows.push(Row { line, cells });
        }
        Ok(Table { file: file.to_path_buf(), header_line, headers, rows, decimal: format.decimal, index })
    }

    /// Index of the column called `name`.
    pub fn col(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    /// Index of the required column `name`, or a `MissingColumn` error.
    pub fn require(&self, name: &str) -> Result<usize> {
        self.col(name).ok_or_else(|| self.missing_column(name))
    }

    /// The `MissingColumn` error for `name`, with a hint when the name occurs in another case or
    /// the header looks like it uses a different delimiter.
    pub fn missing_column(&self, name: &str) -> DatasetError {
        self.missing_column_of(&[name])
    }

    /// The `MissingColumn` error for a column that may have any of the `names` (the first is
    /// reported as the column; the others are listed as alternatives).
    pub fn missing_column_of(&self, names: &[&str]) -> DatasetError {
        let mut hint = String::new();
        if names.len() > 1 {
            hint = format!(" (or {})", names[1..].join(", "));
        }
        if let Some(h) = self.headers.iter().find(|h| names.iter().any(|n| h.eq_ignore_ascii_case(n))) {
            hint.push_str(&format!("; found '{h}' (column names are case-sensitive)"));
        } else if self.headers.len() == 1 && (self.headers[0].contains(';') || self.headers[0].contains('\t')) {
            hint.push_str("; the header has a single column: is the file separated by another character?");
        }
        DatasetError::MissingColumn {
            location: Location::new(&self.file, self.header_line, names.first().copied().unwrap_or("")),
            hint,
        }
    }

    /// Location of the header cell of column `col`.
    pub fn header_loc(&self, col: usize) -> Location {
        Location::new(&self.file, self.header_line, self.headers[col].clone())
    }

    /// Location of a cell.
    pub fn loc(&self, row: &Row, col: usize) -> Location {
        Location::new(&self.file, row.line, self.headers[col].clone())
    }

    /// A required text cell.
    pub fn text<'r>(&self, row: &'r Row, col: usize) -> Result<&'r str> {
        let t = row.cells[col].as_str();
        if t.is_empty() {
            Err(DatasetError::MissingValue { location: self.loc(row, col) })
        } else {
            Ok(t)
        }
    }

    /// A required number.
    pub fn number(&self, row: &Row, col: usize) -> Result<f64> {
        self.opt_number(row, col)?.ok_or_else(|| DatasetError::MissingValue { location: self.loc(row, col) })
    }

    /// An optional number: `None` for an empty cell.
    pub fn opt_number(&self, row: &Row, col: usize) -> Result<Option<f64>> {
        let t = row.cells[col].as_str();
        if t.is_empty() {
            return Ok(None);
        }
        parse_number(t, self.decimal, || self.loc(row, col)).map(Some)
    }
}

/// A header that is one column holding another separator (a spreadsheet saved with European
/// settings: `;` between fields and decimal commas; or tabs): the error that says so, instead
/// of a field count that blames the first data row.
fn other_separator(headers: &[String], file: &Path, line: u64, format: TableFormat) -> Option<DatasetError> {
    let [only] = headers else { return None };
    let (sep, name) = [(b';', "';'"), (b'\t', "tabs"), (b'|', "'|'")]
        .into_iter()
        .find(|(c, _)| *c != format.delimiter && only.as_bytes().contains(c))?;
    let expected = if format.delimiter == b',' { "','".to_string() } else { format!("'{}'", format.delimiter as char) };
    let mut message =
        format!("the header is a single column: the file is separated by {name}, this table by {expected}");
    if sep == b';' && format.decimal == Decimal::Point {
        message.push_str(
            " (a spreadsheet saved with European settings, which also writes decimal commas): save it as CSV with ',' between fields and '.' as the decimal point",
        );
    } else {
        message.push_str(&format!(": save it with {expected} between fields"));
    }
    Some(DatasetError::Invalid { location: Location::new(file, line, "header"), message })
}

/// Parses one number written with the given decimal separator. Errors: decimal comma or point
/// where the other is expected, not a number, not finite.
pub(crate) fn parse_number(text: &str, decimal: Decimal, loc: impl Fn() -> Location) -> Result<f64> {
    let normalised;
    let candidate = match decimal {
        Decimal::Point => text,
        Decimal::Comma => {
            if text.contains('.') {
                return Err(DatasetError::DecimalPoint { location: loc(), text: super::plausible::cut_cell(text) });
            }
            normalised = text.replacen(',', ".", 1);
            normalised.as_str()
        }
    };
    match candidate.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(DatasetError::NonFinite { location: loc(), text: super::plausible::cut_cell(text) }),
        Err(_) => {
            if decimal == Decimal::Point && text.contains(',') && text.replacen(',', ".", 1).parse::<f64>().is_ok() {
                Err(DatasetError::DecimalComma { location: loc(), text: super::plausible::cut_cell(text) })
            } else {
                Err(DatasetError::NotANumber { location: loc(), text: super::plausible::cut_cell(text) })
            }
        }
    }
}

/// Splits delimited text into records: `(line the record starts on, cells)`. Handles quoted
/// cells (`"a, ""b"""`, also across lines), CR LF line ends, comment lines (a `#` at the start of a
/// line, when enabled) and blank lines, which are skipped but counted. Unquoted cells are trimmed;
/// quoted cells keep their content exactly.
fn split_records(text: &str, file: &Path, format: TableFormat) -> Result<Vec<(u64, Vec<String>)>> {
    let b = text.as_bytes();
    let n = b.len();
    let delim = format.delimiter;
    let mut out = Vec::new();
    let mut i = 0;
    let mut line: u64 = 1;
    let to_string = |v: &[u8]| String::from_utf8_lossy(v).into_owned();
    while i < n {
        let eol = b[i..].iter().position(|c| *c == b'\n').map_or(n, |k| i + k);
        let content = &b[i..eol];
        if (format.comments && content.first() == Some(&b'#')) || content.iter().all(u8::is_ascii_whitespace) {
            i = eol + 1;
            line += 1;
            continue;
        }
        let start_line = line;
        let mut cells = Vec::new();
        let mut cur: Vec<u8> = Vec::new();
        let mut quoted = false;
        let mut in_quotes = false;
        let mut quote_line = line;
        let finish = |cur: &mut Vec<u8>, quoted: bool, cells: &mut Vec<String>| {
            let s = to_string(cur);
            cells.push(if quoted { s } else { s.trim().to_string() });
            cur.clear();
        };
        loop {
            if i >= n {
                if in_quotes {
                    return Err(DatasetError::Invalid {
                        location: Location::line(file, quote_line),
                        message: "a quoted cell is not closed before the end of the file".into(),
                    });
                }
                finish(&mut cur, quoted, &mut cells);
                break;
            }
            let c = b[i];
            if in_quotes {
                if c == b'"' {
                    if b.get(i + 1) == Some(&b'"') {
                        cur.push(b'"');
                        i += 2;
                    } else {
                        in_quotes = false;
                        i += 1;
                    }
                    continue;
                }
                if c == b'\n' {
                    line += 1;
                }
                cur.push(c);
                i += 1;
                continue;
            }
            if c == b'"' && !quoted && cur.iter().all(u8::is_ascii_whitespace) {
                in_quotes = true;
                quoted = true;
                quote_line = line;
                cur.clear();
                i += 1;
            } else if c == delim {
                finish(&mut cur, quoted, &mut cells);
                quoted = false;
                i += 1;
            } else if c == b'\n' || (c == b'\r' && matches!(b.get(i + 1), None | Some(b'\n'))) {
                if c == b'\r' {
                    i += 1;
                }
                // Now at the newline (or the end).
                i += 1;
                line += 1;
                finish(&mut cur, quoted, &mut cells);
                break;
            } else if quoted && !c.is_ascii_whitespace() {
                return Err(DatasetError::Invalid {
                    location: Location::line(file, line),
                    message: "text after the closing quote of a quoted cell".into(),
                });
            } else {
                if !quoted {
                    cur.push(c);
                }
                i += 1;
            }
        }
        out.push((start_line, cells));
    }
    Ok(out)
}

fn is_int(s: &str) -> bool {
    let d = s.strip_prefix(['+', '-']).unwrap_or(s);
    !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit())
}

fn is_fraction(s: &str) -> bool {
    let (mant, exp) = match s.find(['e', 'E']) {
        Some(i) => (&s[..i], Some(&s[i + 1..])),
        None => (s, None),
    };
    !mant.is_empty() && mant.bytes().all(|b| b.is_ascii_digit()) && exp.is_none_or(is_int)
}

fn field_count_error(
    file: &Path,
    line: u64,
    headers: &[String],
    cells: &[String],
    format: TableFormat,
    numeric: &dyn Fn(&str) -> bool,
) -> DatasetError {
    if cells.len() > headers.len() {
        if format.delimiter == b',' && format.decimal == Decimal::Point {
            // A decimal comma in a comma-separated table splits one number into two cells; the
            // cells before the first split still line up with the header.
            for i in 0..headers.len() {
                if numeric(&headers[i]) && is_int(&cells[i]) && cells.get(i + 1).is_some_and(|c| is_fraction(c)) {
                    return DatasetError::DecimalComma {
                        location: Location::new(file, line, headers[i].clone()),
                        text: super::plausible::cut_cell(&format!("{},{}", cells[i], cells[i + 1])),
                    };
                }
            }
        }
        DatasetError::FieldCount {
            location: Location::new(
                file,
                line,
                format!("field {} (after the last column '{}')", headers.len() + 1, headers[headers.len() - 1]),
            ),
            found: cells.len(),
            expected: headers.len(),
        }
    } else {
        DatasetError::FieldCount {
            location: Location::new(file, line, headers[cells.len()].clone()),
            found: cells.len(),
            expected: headers.len(),
        }
    }
}
