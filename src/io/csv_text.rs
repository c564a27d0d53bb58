//! `#`-commented CSV text: the part every table loader shares (PROSPECT spectra, spectral
//! columns, sensor responses) — data lines numbered from 1 for error messages, blank lines
//! and `#` comments skipped, the first data line read as the header.

/// A CSV text split into its header and its data rows.
pub struct CsvText<'a> {
    /// Line number (1-based) of the header in the file.
    pub header_line: usize,
    /// The header line, trimmed.
    pub header: &'a str,
    /// The column names, trimmed.
    pub names: Vec<&'a str>,
    rows: Vec<(usize, &'a str)>,
}

impl<'a> CsvText<'a> {
    /// Splits `text`; `None` when it holds no line but blanks and comments (no header).
    pub fn split(text: &'a str) -> Option<Self> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (header_line, header) = lines.next()?;
        Some(CsvText {
            header_line,
            header,
            names: header.split(',').map(str::trim).collect(),
            rows: lines.collect(),
        })
    }

    /// The position of column `name` in the header.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| *n == name)
    }

    /// The data rows: (line number, trimmed fields).
    pub fn rows(&self) -> impl Iterator<Item = (usize, Vec<&'a str>)> + '_ {
        self.rows
            .iter()
            .map(|&(n, l)| (n, l.split(',').map(str::trim).collect()))
    }

    /// The message for a row whose field count differs from the header's (`None`: it agrees).
    pub fn width_error(&self, fields: &[&str]) -> Option<String> {
        (fields.len() != self.names.len()).then(|| {
            format!(
                "expected {} fields, found {}",
                self.names.len(),
                fields.len()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_lines_from_one_and_skips_comments_and_blanks() {
        let t = CsvText::split("# c\n\n a , b \n1,2\n# mid\n\n3,4,5\n").expect("header");
        assert_eq!(t.header_line, 3);
        assert_eq!(t.header, "a , b");
        assert_eq!(t.names, ["a", "b"]);
        assert_eq!(t.column("b"), Some(1));
        assert_eq!(t.column("c"), None);
        let rows: Vec<_> = t.rows().collect();
        assert_eq!(rows, [(4, vec!["1", "2"]), (7, vec!["3", "4", "5"])]);
        assert_eq!(t.width_error(&rows[0].1), None);
        assert_eq!(
            t.width_error(&rows[1].1).as_deref(),
            Some("expected 2 fields, found 3")
        );
    }

    #[test]
    fn a_text_of_comments_has_no_header() {
        assert!(CsvText::split("# only\n\n   \n").is_none());
        assert!(CsvText::split("").is_none());
    }
}
