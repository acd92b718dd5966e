"""ecu-daemon: a chassis-ECU-like estimator of sideslip, heading and sensor biases."""
__version__ = "0.1.0"
