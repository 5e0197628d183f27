"""Gait phase: the phaser, the Fourier gait template and the online phase tracker."""
