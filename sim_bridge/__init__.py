"""Co-simulation of the portal advancing mechanism's movement cycle, and its CAN bridge.

The model (pure computation) produces the leg cylinders' chamber pressures, the other
DBC signals and the true foot forces; the bridge plays them onto a CAN bus per the DBC.
"""
