"""The spacecraft and its motion: scenario, presets, dynamics, actuation, the batched
simulator, the least-squares inertia estimator and the hand-designed sequences."""
