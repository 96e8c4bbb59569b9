//! Writing result tables as CSV and Markdown.

use std::fmt::Write as _;
use std::path::Path;

/// A table of strings with a header row.
pub struct Table {
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new(header: &[&str]) -> Self {
        Table {
            header: header.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    pub fn push(&mut self, row: Vec<String>) {
        debug_assert_eq!(row.len(), self.header.len());
        self.rows.push(row);
    }

    /// RFC 4180: fields holding a comma, quote or line break are quoted.
    pub fn csv(&self) -> String {
        fn field(f: &str) -> String {
            if f.contains([',', '"', '\n', '\r']) {
                format!("\"{}\"", f.replace('"', "\"\""))
            } else {
                f.to_string()
            }
        }
        let line = |r: &[String]| r.iter().map(|f| field(f)).collect::<Vec<_>>().join(",") + "\n";
        let mut s = line(&self.header);
        for r in &self.rows {
            s += &line(r);
        }
        s
    }

    pub fn markdown(&self) -> String {
        let mut s = format!("| {} |\n|", self.header.join(" | "));
        for _ in &self.header {
            s += "---|";
        }
        s.push('\n');
        for r in &self.rows {
            let _ = writeln!(s, "| {} |", r.join(" | "));
        }
        s
    }
}

/// Writes text through a temporary sibling and a rename.
pub fn write_text(path: &Path, text: &str) -> Result<(), super::ReportError> {
    crate::bundle::write::replace_file(path, |tmp| std::fs::write(tmp, text))?;
    Ok(())
}

/// A number for a table: 4 significant digits, `inf` kept readable.
pub fn num(v: f64) -> String {
    if v.is_infinite() {
        "inf".into()
    } else if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e-3 && v.abs() < 1e5 {
        format!("{:.4}", v)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        let s = format!("{v:.3e}");
        match s.split_once('e') {
            Some((m, e)) => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
            None => s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_fields_with_commas_and_quotes() {
        let mut t = Table::new(&["a", "b"]);
        t.push(vec!["x, y".into(), "say \"hi\"".into()]);
        t.push(vec!["1".into(), "2".into()]);
        assert_eq!(t.csv(), "a,b\n\"x, y\",\"say \"\"hi\"\"\"\n1,2\n");
    }
}
