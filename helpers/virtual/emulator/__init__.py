"""The virtual rig's emulated boards: the firmware's protocol in Python, in-process or on pseudo-terminals.

- :mod:`helpers.virtual.emulator.boards`: the DAQ and stepper boards built for a rig file (1-4 channels and
  axes), behaving as the firmware does;
- :mod:`helpers.virtual.emulator.world`: one virtual rig per rig file (the twin, its load cells, both boards,
  one device clock) and the worlds of a process by ``(name, rig hash)``;
- :mod:`helpers.virtual.emulator.protocol_virtual`: the pyserial URL handler ``virtual://daq?world=NAME``
  (the rig given as ``port.rig``);
  pyserial finds it when ``helpers.virtual.emulator`` is in ``serial.protocol_handler_packages``, which
  :func:`helpers.rig.link.open_port` arranges when it is asked to open a ``virtual://`` URL;
- :mod:`helpers.virtual.emulator.server`: ``python -m helpers serve-virtual-rig``, both boards on
  pseudo-terminals.

The physics comes from :mod:`helpers.virtual`, the protocol from :mod:`helpers.board.protocol`; nothing here
imports the host driver (:mod:`helpers.rig`).
"""
