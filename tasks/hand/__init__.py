"""The Barrett BH8-280 hand, shared by grasp planning, simulation and the demonstration scenes."""
