"""Background stage: what every sample sees behind the polygons (terrain, the sky and the
earth plane, clouds), through the haze and the fog (terrain.py, haze.py, clouds.py, air.py)."""
