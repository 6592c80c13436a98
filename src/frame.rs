//! One frame, end to end: scene + time -> water -> refraction -> GPU -> layers. The single entry
//! point used by the CLI and by the tests.
