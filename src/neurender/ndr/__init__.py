"""Neural Direct-illumination Renderer (Suppan et al. 2021): procedural data, model, evaluation."""
