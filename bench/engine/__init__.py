"""The run engine: a state machine that turns sequence steps into device actions.

The engine sees the devices only through the small contracts of :mod:`bench.engine.contracts`, so a
simulated bench, real hardware and a test fake are interchangeable. Front ends (command line,
terminal UI) request transitions and subscribe to events; storage and analysis are subscribers too.
"""
