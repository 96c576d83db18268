"""The technician's terminal UI (Textual): bench, sequence, run, prompts and results screens."""
