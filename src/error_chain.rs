//! An error and its causes as one line, the way the `nephele` command prints them and the
//! Python binding raises them: `outer: cause: …`, each cause said once.

use std::error::Error;

/// The error and its causes as one line, `outer: cause: …`, each cause said once: a library
/// error's message often already ends with its source's (`{path}: {source}`), and the source is
/// also the next link of the chain, so a link whose text the line already holds is left out.
pub fn message(e: &(dyn Error + 'static)) -> String {
    let mut line = String::new();
    let mut link: Option<&(dyn Error + 'static)> = Some(e);
    while let Some(cause) = link {
        let text = cause.to_string();
        if !line.contains(&text) {
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&text);
        }
        link = cause.source();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An error whose message includes its source's, as `thiserror`'s `{path}: {source}` does.
    #[derive(Debug)]
    struct Wrapping(std::io::Error);

    impl std::fmt::Display for Wrapping {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "frame.exr: {}", self.0)
        }
    }

    impl Error for Wrapping {
        fn source(&self) -> Option<&(dyn Error + 'static)> {
            Some(&self.0)
        }
    }

    /// An error that names its source only through `source()`.
    #[derive(Debug)]
    struct Outer(Wrapping);

    impl std::fmt::Display for Outer {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("rendering shot.ron")
        }
    }

    impl Error for Outer {
        fn source(&self) -> Option<&(dyn Error + 'static)> {
            Some(&self.0)
        }
    }

    #[test]
    fn each_cause_is_said_once() {
        let disk = std::io::Error::from_raw_os_error(28);
        let cause = disk.to_string();
        let line = message(&Outer(Wrapping(disk)));
        assert_eq!(line, format!("rendering shot.ron: frame.exr: {cause}"));
        assert_eq!(line.matches(&cause).count(), 1, "{line}");
    }
}
