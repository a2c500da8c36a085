"""Scene database stage: the scene file loaded and checked (load.py) into the Database the
pipeline reads every frame (database.py), its atmosphere (atmosphere.py) and the voxel terrain
database (terrain/)."""
