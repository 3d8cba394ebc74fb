"""The exact check: continuous-time separation of every pair, and of every UAV
from the blocked cells."""
