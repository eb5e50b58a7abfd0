"""The Wiimote protocol, one module per feature (as Linux's hid-wiimote and wiiuse split it):
``reports`` (report ids, output reports, status and acks), ``buttons``, ``accel``, ``ir``,
``memory`` (register/EEPROM reads and writes), ``nunchuk``; ``driver`` ties them to a transport.
Parsers are pure functions of bytes → typed events; I/O, timing and retries live in the driver.
"""
