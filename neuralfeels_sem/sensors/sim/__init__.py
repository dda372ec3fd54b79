"""sensor=sim: the simulated rig (MuJoCo hand + pyrender DIGITs and camera) as a Sensor."""

from neuralfeels_sem.sensors.sim.sim_sensor import SimSensor

__all__ = ["SimSensor"]
