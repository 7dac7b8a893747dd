"""Import of other tools' recordings: stream reading, sample clocks, merging onto one time base."""
