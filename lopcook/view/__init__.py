"""``lopcook view``: the streaming viewer served on 127.0.0.1 (docs/viewer.md).

``server`` answers a fixed set of URLs (ranges, pacing, 404 for anything else), ``site`` builds
the set ``lopcook view`` serves: the page in ``runtime/js/viewer/`` and one container with its
materials.
"""

from .server import Route, Site, ViewerServer, parse_range
from .site import add_container, runtime_js_dir, runtime_site, viewer_site

__all__ = ["Route", "Site", "ViewerServer", "add_container", "parse_range", "runtime_js_dir", "runtime_site",
           "viewer_site"]
