"""CIGI (Common Image Generator Interface, SISO-STD-013) on the wire: versions 3.2, 3.3 and 4.0.

`packets` holds the typed packets (frozen dataclasses, snake_case fields), `codec` turns
datagrams into `Message`s and packets into datagrams, `scripted_host` plays a CIGI 3.3 host over
UDP against an IG for tests. Importing this package imports none of them.
"""
