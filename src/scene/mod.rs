//! Scene files (RON): a target, an animation scheme, camera, lighting, material, shot and
//! output settings; and rendering a shot to frame files with resume and frame ranges.
