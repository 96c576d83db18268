"""The simulated plant: a bench and its specimen in the time domain, as its sensors see it."""

from simulators.plant.actuator import IdealServo, ServoActuator
from simulators.plant.excitation import HalfSinePulse, SampledDrive, SineDwell, Sweep, Waveform
from simulators.plant.sensors import SensorRealism
from simulators.plant.simulator import PlantSimulator

__all__ = [
    "HalfSinePulse",
    "IdealServo",
    "PlantSimulator",
    "SampledDrive",
    "SensorRealism",
    "ServoActuator",
    "SineDwell",
    "Sweep",
    "Waveform",
]
