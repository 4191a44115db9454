"""skrl's PPO on a wrapped vector environment, small enough for the suite: the models, the agent and
its trainer, written once for every integration test that drives the environment with skrl."""

import torch


def train_skrl_ppo(env, directory, hidden: int, timesteps: int):
    """Train skrl's PPO (rollouts of 16 steps) on ``env`` for ``timesteps`` steps and return the agent.

    Args:
        env: the environment wrapped by ``skrl.envs.wrappers.torch.wrap_env``.
        directory: where skrl writes its experiment (nothing is written at these intervals).
        hidden: the width of the policy's and the value's hidden layer.
        timesteps: the trainer's steps.
    """
    from skrl.agents.torch.ppo import PPO, PPO_CFG
    from skrl.memories.torch import RandomMemory
    from skrl.models.torch import DeterministicMixin, GaussianMixin, Model
    from skrl.trainers.torch import SequentialTrainer

    class Policy(GaussianMixin, Model):
        def __init__(self, observation_space, action_space, device):
            Model.__init__(self, observation_space=observation_space, action_space=action_space, device=device)
            GaussianMixin.__init__(self, clip_actions=True)
            self.net = torch.nn.Sequential(
                torch.nn.Linear(self.num_observations, hidden),
                torch.nn.Tanh(),
                torch.nn.Linear(hidden, self.num_actions),
            )
            self.log_std = torch.nn.Parameter(torch.full((self.num_actions,), -1.0))

        def compute(self, inputs, role=""):
            return self.net(inputs["observations"]), {"log_std": self.log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self, observation_space, device):
            Model.__init__(self, observation_space=observation_space, device=device)
            DeterministicMixin.__init__(self)
            self.net = torch.nn.Sequential(
                torch.nn.Linear(self.num_observations, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, 1)
            )

        def compute(self, inputs, role=""):
            return self.net(inputs["observations"]), {}

    cfg = PPO_CFG(rollouts=16, learning_epochs=2, mini_batches=2)
    cfg.experiment.directory = str(directory)
    cfg.experiment.write_interval = 0
    cfg.experiment.checkpoint_interval = 0
    agent = PPO(
        models={
            "policy": Policy(env.observation_space, env.action_space, env.device),
            "value": Value(env.observation_space, env.device),
        },
        memory=RandomMemory(memory_size=16, num_envs=env.num_envs, device=env.device),
        observation_space=env.observation_space,
        action_space=env.action_space,
        device=env.device,
        cfg=cfg,
    )
    trainer = SequentialTrainer(
        env=env,
        agents=agent,
        cfg={"timesteps": timesteps, "disable_progressbar": True, "close_environment_at_exit": False},
    )
    trainer.train()
    return agent
