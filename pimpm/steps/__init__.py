"""The steps of a simulation, one module each, siblings with the same entry
point ``advance(sim, dt)``: :mod:`.implicit` (Guilkey & Weiss 2003, section
3.3, steps 1-8) and :mod:`.explicit` (the explicit MPM step of the MPM
introduction, eq. 1-10). :meth:`pimpm.simulation.Simulation.advance`
chooses one by the run's integrator."""
