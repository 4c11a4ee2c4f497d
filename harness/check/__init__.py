"""The offline G-code checker (`pkmbench check`): :mod:`.gcode`."""
