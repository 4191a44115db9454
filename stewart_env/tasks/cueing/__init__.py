"""Motion cueing: the vehicle motion a simulator reproduces, and how a person perceives it."""
