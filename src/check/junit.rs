//! JUnit XML for CI systems: receives a [`DiffReport`] and returns (or atomically writes) one
//! `<testsuite>` with one `<testcase>` per frame. A failing frame carries a `<failure>` with the
//! reasons; a warning is not a JUnit state, so a warning frame passes and carries the reasons in
//! `<system-out>` prefixed `warning:` (CI shows it without failing the job; the exit code still
//! says 1).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use super::{DiffReport, Verdict};
use crate::output::OutputError;

/// The report as JUnit XML; `suite_name` names the test suite (e.g. `snell diff` or the scene).
pub fn junit_xml(suite_name: &str, report: &DiffReport) -> String {
    let tests = report.frames.len();
    let failures = report.count(Verdict::Fail);
    let total_secs: f64 = report.frames.iter().map(|frame| frame.elapsed_secs).sum();
    let suite = escape(suite_name);
    let mut xml = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        xml,
        "<testsuites name=\"{suite}\" tests=\"{tests}\" failures=\"{failures}\" errors=\"0\" time=\"{total_secs:.3}\">"
    );
    let _ = writeln!(
        xml,
        "  <testsuite name=\"{suite}\" tests=\"{tests}\" failures=\"{failures}\" errors=\"0\" skipped=\"0\" time=\"{total_secs:.3}\">"
    );
    for frame in &report.frames {
        let _ = write!(
            xml,
            "    <testcase classname=\"{suite}\" name=\"{}\" time=\"{:.3}\"",
            escape(&frame.name),
            frame.elapsed_secs
        );
        let metrics = frame
            .metrics
            .as_ref()
            .map(|m| {
                format!(
                    "FLIP mean {:.5}, p99 {:.5}; Z off in {} px, P off in {} px",
                    m.flip_mean, m.flip_p99, m.depth.exceeding_pixels, m.position.exceeding_pixels
                )
            })
            .unwrap_or_default();
        match frame.verdict() {
            Verdict::Pass if metrics.is_empty() => xml.push_str("/>\n"),
            Verdict::Pass => {
                let _ = writeln!(
                    xml,
                    ">\n      <system-out>{}</system-out>\n    </testcase>",
                    escape(&metrics)
                );
            }
            Verdict::Warn => {
                let _ = writeln!(
                    xml,
                    ">\n      <system-out>warning: {}\n{}</system-out>\n    </testcase>",
                    escape(&frame.reasons()),
                    escape(&metrics)
                );
            }
            Verdict::Fail => {
                let _ = writeln!(
                    xml,
                    ">\n      <failure message=\"{}\" type=\"frame-diff\">{}\n{}</failure>\n    </testcase>",
                    escape(&frame.reasons()),
                    escape(&format!(
                        "reference {}\ntest {}",
                        frame.reference.display(),
                        frame.test.display()
                    )),
                    escape(&metrics)
                );
            }
        }
    }
    xml.push_str("  </testsuite>\n</testsuites>\n");
    xml
}

/// Writes [`junit_xml`] to `path` via a synced temporary file and a rename.
pub fn write_junit(path: &Path, suite_name: &str, report: &DiffReport) -> Result<(), OutputError> {
    let xml = junit_xml(suite_name, report);
    crate::output::write_atomically(path, |file| {
        file.write_all(xml.as_bytes())
            .map_err(|error| error.to_string())
    })
}

/// Escapes text for an XML attribute or element. Characters XML 1.0 forbids even as references
/// (control characters other than tab, newline, carriage return) become U+FFFD.
pub fn escape(text: &str) -> String {
    let mut escaped = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => escaped.push_str("&amp;"),
            '<' => escaped.push_str("&lt;"),
            '>' => escaped.push_str("&gt;"),
            '"' => escaped.push_str("&quot;"),
            '\'' => escaped.push_str("&apos;"),
            '\t' | '\n' | '\r' => escaped.push(c),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => {
                escaped.push('\u{FFFD}')
            }
            c => escaped.push(c),
        }
    }
    escaped
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_handles_markup_quotes_and_forbidden_characters() {
        assert_eq!(
            escape("a<b>&\"c'\u{1}\td"),
            "a&lt;b&gt;&amp;&quot;c&apos;\u{FFFD}\td"
        );
    }
}
