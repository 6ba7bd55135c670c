//! Metro-style evaluation (Cignoni et al. 1998): sample both surfaces, nearest-point distances
//! through a BVH in both directions, mean / RMS / max and the Hausdorff distance.
