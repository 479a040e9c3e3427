"""Signals shared by identification and the HIL adapter: PWM mapping, FMU output -> log names."""
