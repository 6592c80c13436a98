//! Speed against accuracy (`snell chart`, and a scene's `max_error_px`): the chart drawing first;
//! the measurements follow once the reference tracer and the exact method are in.

pub mod plot;
