"""Appearance-driven simplification (Hasselgren et al. 2021): a low-polygon mesh with
textures, optimised through Mitsuba 3 to match a reference renderer's images."""
