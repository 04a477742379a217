"""What both ends know about the wire, in one copy: the companion (``companion.link``) and the
simulated vehicle (``sitl``) import it.

- :mod:`.wire`: datagram parsing (one clean parser state per datagram, counts instead of raises);
- :mod:`.udp` (and :mod:`.stream` for serial and TCP): the endpoints that read every waiting datagram;
- :mod:`.signing`, :mod:`.signing_options`: MAVLink 2 signing, keys, the command-line options;
- :mod:`.modes`: PX4's and ArduCopter's mode numbers and names;
- :mod:`.events`: PX4's EVENT messages decoded to text;
- :mod:`.params`: parameter names and values as the wire carries them.

No asyncio beyond the endpoints, no control code.
"""
