"""Views' data, one module per view kind: plain Python over a Source, no UI toolkit.

The Source is the live Hub or a log's playback (debug_gui.source).

A model ``XModel(source, robot, ...)`` creates its feeds in ``activate()`` at the rate its view
displays and closes them in ``deactivate()`` (a hidden view costs the robot nothing); feed
callbacks run on executor threads, so its state sits behind a lock. While active it
registers ``reset()`` with the source's ``on_reset`` (a seek: it forgets what it
accumulated), and it judges ages on the source's clock by its messages' stamps
(:mod:`.ages`); ``clock=`` replaces the source's clock in tests.
"""
