//! Camera pairs on the command line: `REFERENCE:TARGET`, e.g. `0:4`.

/// Parses `R:T` into two distinct camera indices.
pub fn parse_pair(s: &str) -> Result<(usize, usize), String> {
    let usage = || format!("invalid pair {s:?}: expected REFERENCE:TARGET, e.g. 0:1");
    let (r, t) = s.split_once(':').ok_or_else(usage)?;
    let pair: (usize, usize) = (
        r.trim().parse().map_err(|_| usage())?,
        t.trim().parse().map_err(|_| usage())?,
    );
    if pair.0 == pair.1 {
        return Err(format!(
            "invalid pair {s:?}: reference and target must differ"
        ));
    }
    Ok(pair)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_parse_and_must_differ() {
        assert_eq!(parse_pair("2:1"), Ok((2, 1)));
        assert_eq!(parse_pair(" 0 : 4"), Ok((0, 4)));
        assert!(parse_pair("1:1").unwrap_err().contains("must differ"));
        assert!(
            parse_pair("21")
                .unwrap_err()
                .contains("expected REFERENCE:TARGET")
        );
        assert!(parse_pair("a:1").is_err());
    }
}
