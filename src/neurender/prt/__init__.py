"""DeepPRT (Hong et al.): geometry images, deformations, ray-traced SH transfer."""
