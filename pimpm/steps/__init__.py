"""The steps of a simulation, one module each: :mod:`.explicit` (the explicit
MPM step of the MPM introduction, eq. 1-10). The implicit step of Guilkey &
Weiss (section 3.3) is :meth:`pimpm.simulation.Simulation.advance`."""
