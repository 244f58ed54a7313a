"""piezo-turntable: simulator and controller environment for the piezo stick–slip turntable.

Specification: M. Schepers, *Modeling a Piezoelectric Inertial Stepping Turntable
Using Bond Graphs* (M.Sc. thesis, U. Twente). Physics parts: :mod:`.piezo`,
:mod:`.tube`, :mod:`.table`, :mod:`.geometry`, :mod:`.friction`, :mod:`.drive`,
:mod:`.amplifier`, :mod:`.detector`; parameter sets in :mod:`.params`.
"""

__version__ = "0.1.0"
