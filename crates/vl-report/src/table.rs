//! Results printed for people: rows of cells in aligned columns, the same
//! on a console and in a Markdown report's code blocks.

use std::fmt;

/// A result people read as a table and programs as JSON: its table is
/// written beside the type so every command and window shows it alike.
pub trait Report: serde::Serialize {
    /// The result as people read it.
    fn table(&self) -> Table;
}

/// Rows of cells printed in aligned columns: the first column to the
/// left, the others (figures) to the right; a table of pairs keeps its
/// values to the left. Lines before and after it stay as they are.
#[derive(Debug, Default)]
pub struct Table {
    before: Vec<String>,
    header: Option<Vec<String>>,
    rows: Vec<Vec<String>>,
    after: Vec<String>,
    /// Name–value rows: values to the left.
    pairs: bool,
}

impl Table {
    /// A table of names and values.
    pub fn pairs<'a>(rows: impl IntoIterator<Item = (&'a str, String)>) -> Table {
        Table {
            rows: rows
                .into_iter()
                .map(|(name, value)| vec![name.to_owned(), value])
                .collect(),
            pairs: true,
            ..Table::default()
        }
    }

    /// A table with a header row; add rows with [`Table::row`].
    pub fn columns(header: &[&str]) -> Table {
        Table {
            header: Some(header.iter().map(|h| (*h).to_owned()).collect()),
            ..Table::default()
        }
    }

    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }

    /// A line printed above the table.
    pub fn title(mut self, line: impl Into<String>) -> Table {
        self.before.push(line.into());
        self
    }

    /// A line printed below the table.
    pub fn note(mut self, line: impl Into<String>) -> Table {
        self.after.push(line.into());
        self
    }
}

impl Table {
    /// The table as a Markdown table (lines before and after as
    /// paragraphs): figures to the right, as on a console.
    pub fn markdown(&self) -> String {
        let mut out = String::new();
        for line in &self.before {
            out.push_str(line);
            out.push_str("\n\n");
        }
        let cell = |c: &str| c.replace('|', "\\|");
        let columns = self
            .header
            .iter()
            .chain(&self.rows)
            .map(Vec::len)
            .max()
            .unwrap_or(0);
        let header: Vec<String> = match &self.header {
            Some(h) => h.iter().map(|c| cell(c)).collect(),
            None => vec![String::new(); columns],
        };
        out.push_str(&format!("| {} |\n", header.join(" | ")));
        // Figures to the right; a column of words (names, kinds) to the left.
        let figures = |c: usize| {
            self.rows.iter().filter_map(|r| r.get(c)).all(|cell| {
                cell.is_empty()
                    || cell.starts_with(|ch: char| ch.is_ascii_digit() || "–-+".contains(ch))
            })
        };
        let rule: Vec<&str> = (0..columns)
            .map(|c| {
                if c == 0 || self.pairs || !figures(c) {
                    ":--"
                } else {
                    "--:"
                }
            })
            .collect();
        out.push_str(&format!("|{}|\n", rule.join("|")));
        for row in &self.rows {
            let cells: Vec<String> = row.iter().map(|c| cell(c)).collect();
            out.push_str(&format!("| {} |\n", cells.join(" | ")));
        }
        for line in &self.after {
            out.push('\n');
            out.push_str(line);
            out.push('\n');
        }
        out
    }
}

impl fmt::Display for Table {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for line in &self.before {
            writeln!(f, "{line}")?;
        }
        let lines: Vec<&Vec<String>> = self.header.iter().chain(&self.rows).collect();
        let columns = lines.iter().map(|l| l.len()).max().unwrap_or(0);
        let width = |c: usize| {
            lines
                .iter()
                .filter_map(|l| l.get(c))
                .map(|cell| cell.chars().count())
                .max()
                .unwrap_or(0)
        };
        let widths: Vec<usize> = (0..columns).map(width).collect();
        for line in lines {
            let mut text = String::new();
            for (c, cell) in line.iter().enumerate() {
                let pad = widths[c] - cell.chars().count();
                let last = c + 1 == line.len();
                if c > 0 {
                    text.push_str("  ");
                }
                if c == 0 || self.pairs {
                    text.push_str(cell);
                    if !last {
                        text.push_str(&" ".repeat(pad));
                    }
                } else {
                    text.push_str(&" ".repeat(pad));
                    text.push_str(cell);
                }
            }
            writeln!(f, "{}", text.trim_end())?;
        }
        for line in &self.after {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }
}

/// "1 token", "2 tokens": a count with its noun, singular or plural.
pub fn count(n: impl Into<u64>, singular: &str, plural: &str) -> String {
    let n = n.into();
    format!("{n} {}", if n == 1 { singular } else { plural })
}

/// "yes" or "no".
pub fn yes(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_align_by_characters_not_bytes() {
        let mut t = Table::columns(&["model", "states", "θ"]);
        t.row(vec!["a".into(), "1".into(), "°".into()]);
        t.row(vec!["longer".into(), "12345".into(), "10°".into()]);
        assert_eq!(
            t.to_string(),
            "model   states    θ\n\
             a            1    °\n\
             longer   12345  10°\n"
        );
        let p = Table::pairs([("net", "x".to_owned()), ("bounded", "yes".to_owned())]);
        assert_eq!(p.to_string(), "net      x\nbounded  yes\n");
        assert_eq!(count(1u32, "token", "tokens"), "1 token");
        assert_eq!(count(0u32, "token", "tokens"), "0 tokens");
    }
}

#[cfg(test)]
mod markdown_tests {
    use super::Table;

    #[test]
    fn a_table_in_markdown_keeps_its_figures_right_and_escapes_bars() {
        let mut t = Table::columns(&["profile", "tracking, mm"]);
        t.row(vec!["lan".into(), "1.2 ± 0.3".into()]);
        t.row(vec!["a|b".into(), "4".into()]);
        let md = t.note("n = 5 seeds").markdown();
        assert_eq!(
            md,
            "| profile | tracking, mm |\n|:--|--:|\n| lan | 1.2 ± 0.3 |\n| a\\|b | 4 |\n\nn = 5 seeds\n"
        );
    }
}

/// `unix_ms` (ms since 1970, UTC) as people read a time of day:
/// "2026-11-27 10:52 UTC". (Days to a civil date as in Howard Hinnant's
/// `civil_from_days`.)
pub fn utc(unix_ms: u64) -> String {
    let minutes = unix_ms / 60_000;
    let (days, minute_of_day) = ((minutes / 1440) as i64, minutes % 1440);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year}-{month:02}-{day:02} {:02}:{:02} UTC",
        minute_of_day / 60,
        minute_of_day % 60
    )
}

#[cfg(test)]
mod utc_tests {
    use super::utc;

    #[test]
    fn days_since_1970_are_calendar_dates() {
        assert_eq!(utc(0), "1970-01-01 00:00 UTC");
        // 2000-02-29, a leap day in a century year.
        assert_eq!(utc(951_782_400_000 + 90_000), "2000-02-29 00:01 UTC");
        assert_eq!(utc(1_795_764_149_849), "2026-11-27 07:22 UTC");
        assert_eq!(utc(4_102_444_799_000), "2099-12-31 23:59 UTC");
    }
}
