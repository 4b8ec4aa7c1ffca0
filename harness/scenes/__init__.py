"""What is simulated: the case files and each scene's parsing, truth, metrics and checks against theory."""
