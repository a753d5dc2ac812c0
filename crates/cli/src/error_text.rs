//! The one-line text of an error and its causes, as printed by `motus` on failure.

/// The error and each cause not already spelled out by the text before it, joined by
/// ": ". Many library errors quote their cause in their own message (`"{axis}: {source}"`),
/// so printing the whole chain (`{:#}`) would repeat it.
pub fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::error_text;

    #[derive(Debug, thiserror::Error)]
    #[error("the line went quiet")]
    struct Quiet;

    #[derive(Debug, thiserror::Error)]
    #[error("pan: {source}")]
    struct Quoting {
        source: Quiet,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("pan failed")]
    struct Terse {
        #[source]
        source: Quiet,
    }

    #[test]
    fn a_cause_quoted_in_the_message_is_printed_once() {
        let e = anyhow::Error::new(Quoting { source: Quiet }).context("where 0.1");
        assert_eq!(error_text(&e), "where 0.1: pan: the line went quiet");
    }

    #[test]
    fn a_cause_not_quoted_is_appended() {
        let e = anyhow::Error::new(Terse { source: Quiet });
        assert_eq!(error_text(&e), "pan failed: the line went quiet");
    }
}
