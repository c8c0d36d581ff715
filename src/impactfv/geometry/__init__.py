"""Contact geometry shared by the FV contact and the FE baselines' contact: surfaces of
bodies and regions, uniform-bin search, and the start-up overlap check."""
