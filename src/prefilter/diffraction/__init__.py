"""Diffraction from nanostructure height fields: Stam 1999 with the Taylor/FFT terms of Single 2013."""
