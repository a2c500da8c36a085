"""The compositor's live view (docs/live-view.md): the stitched panorama and the rig's state on a
web page, served by a thread of the compositor process, never holding the rig up.

    frames.py    the newest composite, scaled down and encoded as JPEG on the view's own thread,
                 handed to every browser through a mailbox of one (dropped frames counted)
    status.py    what the page shows besides the picture: channels, frames, latency, seams
    endpoint.py  the HTTP(S) server: the page, the MJPEG stream, status.json
    page.html    the page itself (no external resources: it works offline)
"""
