//! The preview page: one self-contained HTML file (styles and script inline, no external
//! resources), compiled into the binary.

pub(super) const PAGE: &str = include_str!("page.html");
