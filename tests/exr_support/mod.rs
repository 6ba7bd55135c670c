//! Reading EXR files back in the render and export tests.

use std::path::Path;

use exr::prelude::*;

/// The first layer of the EXR at `path` (every channel, every attribute), read with the `exr`
/// crate.
pub fn read_first_layer(path: &Path) -> Layer<AnyChannels<FlatSamples>> {
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .unwrap()
        .layer_data
        .into_iter()
        .next()
        .unwrap()
}
