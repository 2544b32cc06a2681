"""The diagnosis of the sim-to-real gap: where measurements and the model disagree, which effect explains it, how far it closes."""
