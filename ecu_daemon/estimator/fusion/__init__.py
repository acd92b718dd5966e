"""One module per aiding source (PX4 EKF2 style): each decides whether its measurement is usable
now, forms the innovation and its noise, and calls the shared update in ``kalman.py``."""
