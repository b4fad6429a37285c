"""Views' data, one module per view kind: plain Python over the Hub, no UI toolkit.

A model ``XModel(hub, robot, ...)`` creates its feeds in ``activate()`` at the rate its view
displays and closes them in ``deactivate()`` (a hidden view costs the robot nothing); feed
callbacks run on executor threads, so its state sits behind a lock.
"""
