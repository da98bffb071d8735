//! A table of text cells written the two ways every evaluation report is printed: Markdown (for
//! the docs) or plain text in aligned columns (for a terminal).

use std::fmt::Write;

/// How a column's cells line up: names to the left, numbers to the right.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    Left,
    Right,
}

/// Appends `header` and `rows` to `out`: as Markdown (the separator row says each column's
/// alignment), or as plain text, columns two spaces apart and padded to their widest cell.
pub fn write_table<const N: usize>(out: &mut String, header: [&str; N], align: [Align; N], rows: &[[String; N]], markdown: bool) {
    if markdown {
        let _ = writeln!(out, "| {} |", header.join(" | "));
        let separator: String = align.iter().map(|a| if *a == Align::Right { "---:|" } else { "---|" }).collect();
        let _ = writeln!(out, "|{separator}");
        for r in rows {
            let _ = writeln!(out, "| {} |", r.join(" | "));
        }
        return;
    }
    let widths: [usize; N] =
        std::array::from_fn(|c| rows.iter().map(|r| r[c].chars().count()).chain([header[c].chars().count()]).max().unwrap_or(0));
    let line = |cells: &[String]| -> String {
        let parts: Vec<String> = cells
            .iter()
            .enumerate()
            .map(|(c, s)| match align[c] {
                Align::Left => format!("{s:<w$}", w = widths[c]),
                Align::Right => format!("{s:>w$}", w = widths[c]),
            })
            .collect();
        parts.join("  ").trim_end().to_owned()
    };
    let _ = writeln!(out, "{}", line(&header.map(str::to_owned)));
    for r in rows {
        let _ = writeln!(out, "{}", line(r));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_marks_right_aligned_columns_and_plain_text_pads_them() {
        let rows = [["a".to_owned(), "1.5".to_owned()], ["long name".to_owned(), "10.25".to_owned()]];
        let mut md = String::new();
        write_table(&mut md, ["agent", "score"], [Align::Left, Align::Right], &rows, true);
        assert_eq!(md, "| agent | score |\n|---|---:|\n| a | 1.5 |\n| long name | 10.25 |\n");
        let mut text = String::new();
        write_table(&mut text, ["agent", "score"], [Align::Left, Align::Right], &rows, false);
        assert_eq!(text, "agent      score\na            1.5\nlong name  10.25\n");
    }
}
