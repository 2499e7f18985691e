//! The list-file format every list option reads (`--frames`, `--list`): one
//! entry a line, surrounding blanks trimmed, blank lines and `#` comments
//! (to the end of the line) ignored.

/// The entries of a list file's `text`, in order.
pub fn list_entries(text: &str) -> Vec<String> {
    text.lines()
        .map(|line| line.split('#').next().unwrap_or_default().trim())
        .filter(|entry| !entry.is_empty())
        .map(str::to_string)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blanks_and_comments_are_not_entries() {
        let text = "# header\n a.png \n\nb/c.jpg # a comment\n   # only a comment\n";
        assert_eq!(list_entries(text), ["a.png", "b/c.jpg"]);
    }
}
