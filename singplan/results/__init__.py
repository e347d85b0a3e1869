"""The planned trajectory record, its building from the planned moves, lossless save/load."""
