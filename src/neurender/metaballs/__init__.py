"""Image-space metaballs (thesis): scenes, ray-marched targets, circle inputs, AB packing."""
