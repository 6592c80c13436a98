//! Stage 5, output: multi-layer OpenEXR frames written atomically, the per-frame JSONL report,
//! tone-mapped PNG previews, and image comparison (FLIP) for golden tests. OWNER: output helper.
