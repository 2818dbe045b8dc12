"""Python side of mapmesh: the launcher (scripts/swarm) and its helpers. Standard library only
(plots, later, use Debian's python3-matplotlib and python3-numpy)."""
