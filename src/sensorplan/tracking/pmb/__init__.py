"""The track-oriented Poisson multi-Bernoulli (PMB) filter for an unknown number of targets."""
