"""Test sequences: the step vocabulary, the sequence-file loader and validator, standard files."""
