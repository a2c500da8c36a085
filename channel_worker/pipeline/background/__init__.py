"""Background stage: what every sample sees behind the polygons (terrain, the sky and the
earth plane, clouds), through the haze and the fog (background.py is the stage's entry)."""
