"""CIGI queries answered from the scene and terrain databases: height of terrain (heights.py),
line of sight (sight.py) and the gRPC service a channel worker serves them with (service.py);
docs/cigi-queries.md."""
