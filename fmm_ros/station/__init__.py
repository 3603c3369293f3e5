"""The operator's station: the rig live in a browser, each hit judged as it lands.

`state` turns what the rig publishes into the page's JSON (decimated for display), `server`
serves the page and its event stream (tornado, on 127.0.0.1 by default); the ROS node
(`fmm_ros.ros.nodes.station`) only translates messages into them.
"""
