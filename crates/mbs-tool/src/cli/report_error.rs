//! How errors are printed: the message and its causes, each once.

use std::error::Error;

/// The error and its causes joined by `: `, like anyhow's `{:#}`, but a
/// cause whose text the message before it already ends with is left out
/// (readers put their cause in their own message: `a.png: No such file`).
pub fn describe(error: &anyhow::Error) -> String {
    describe_error(error.as_ref())
}

/// [`describe`] of any error: it and its causes (`source()`, one after
/// the other, as anyhow's chain walks them).
pub fn describe_error(error: &(dyn Error + 'static)) -> String {
    let mut out = String::new();
    for cause in std::iter::successors(Some(error), |&e| e.source()) {
        let text = cause.to_string();
        if out.ends_with(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

/// `describe(error)`, prefixed with `name: ` unless the message already
/// starts with it (most messages name their file first).
pub fn describe_item(name: &str, error: &anyhow::Error) -> String {
    describe_item_error(name, error.as_ref())
}

/// [`describe_item`] of any error.
pub fn describe_item_error(name: &str, error: &(dyn Error + 'static)) -> String {
    let text = describe_error(error);
    if text.starts_with(name) {
        text
    } else {
        format!("{name}: {text}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;
    use std::path::Path;

    #[test]
    fn a_cause_already_in_the_message_is_printed_once() {
        let missing = mbs_core::formats::rgb::read_rgb(Path::new("/no/such/a.png")).unwrap_err();
        let error = anyhow::Error::from(missing);
        let text = describe(&error);
        assert_eq!(text.matches("/no/such/a.png").count(), 1, "{text}");
        assert_eq!(text.matches("No such file").count(), 1, "{text}");
        assert_eq!(describe_item("/no/such/a.png", &error), text);
        assert_eq!(describe_item("pair 3", &error), format!("pair 3: {text}"));
    }

    #[test]
    fn context_and_distinct_causes_are_all_kept() {
        let error = Err::<(), _>(std::io::Error::other("disk full"))
            .context("writing out.png")
            .unwrap_err();
        assert_eq!(describe(&error), "writing out.png: disk full");
    }
}
