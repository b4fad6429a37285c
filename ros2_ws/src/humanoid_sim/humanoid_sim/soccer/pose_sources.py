"""The names of the sources of a robot's ``localization/pose`` (:mod:`.localization`), in a
module of their own so that a command line offers them without importing the filter."""

PARTICLE_FILTER = "particle_filter"
NOISY_GROUND_TRUTH = "noisy_ground_truth"
GROUND_TRUTH = "ground_truth"
SOURCES = (PARTICLE_FILTER, NOISY_GROUND_TRUTH, GROUND_TRUTH)
