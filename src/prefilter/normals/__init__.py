"""Fournier 1992: normal-distribution pyramids, multiple surfaces and horizon maps."""
