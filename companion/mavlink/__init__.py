"""What both ends know about the wire, in one copy: the companion (``companion.link``) and the
simulated vehicle (``sitl``) import it.

- :mod:`.wire`: datagram parsing (one clean parser state per datagram, counts instead of raises);
- :mod:`.udp` (and :mod:`.stream` for serial and TCP): the endpoints that read every waiting datagram;
- :mod:`.signing`, :mod:`.signing_options`: MAVLink 2 signing, keys, the command-line options;
- :mod:`.modes`: PX4's and ArduCopter's mode numbers and names;
- :mod:`.events`: PX4's EVENT messages decoded to text;
- :mod:`.params`: parameter names and values as the wire carries them;
- :mod:`.commands`: command numbers pymavlink lacks, and MAV_RESULT / MAV_CMD as words;
- :mod:`.setpoints`: the type_masks of the setpoints the companion sends, for both ends;
- :mod:`.identity`: which vehicle on a link is ours, and two senders that claim one identity;
- :mod:`.boot_time`: time_boot_ms unwrapped across its 49.7-day wrap;
- :mod:`.ftp`: MAVLink FTP frames (the event catalogue's download);
- :mod:`.airframe`: what a vehicle's MAVLink says about its airframe (rotors) and whether it flies.

Protocol numbers come from pymavlink's generated constants or from here, never typed bare
(tests/test_protocol_constants.py).

No asyncio beyond the endpoints, no control code.
"""
