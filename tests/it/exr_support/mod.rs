//! Reading EXR files back in the render and export tests.

use std::path::Path;

use exr::prelude::*;

/// The whole EXR at `path` (image attributes, every layer, channel and attribute), read with
/// the `exr` crate.
pub fn read_image(path: &Path) -> Image<Layers<AnyChannels<FlatSamples>>> {
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .unwrap()
}

/// The first layer of the EXR at `path` (every channel, every attribute).
pub fn read_first_layer(path: &Path) -> Layer<AnyChannels<FlatSamples>> {
    read_image(path).layer_data.into_iter().next().unwrap()
}
