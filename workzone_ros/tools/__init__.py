"""Command-line tools: launcher, bag player/recorder/echo, training, evaluation, benchmarks."""
