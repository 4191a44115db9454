"""The shipped configs, installed as ``stewart_env.configs``: ``platforms/``, the platform
parameters, and ``agents/``, the rl-baselines3-zoo hyperparameters of the training."""
