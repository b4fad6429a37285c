"""Dynamixel Protocol 2.0 servos in software: the bus a real driver (dynamixel-sdk) talks to.

``protocol`` packets (CRC, byte stuffing, parsing); ``control_table`` a servo model's
documented addresses; ``servo`` one servo's control table and rules; ``bus`` the
instructions (ping, read, write, reg/action, sync and bulk read/write, broadcast rules);
``pty`` serves a bus on a pseudo-terminal whose path the driver opens instead of
/dev/ttyUSB0; ``plant`` what moves the joints (a MuJoCo model, or a test double).
"""
