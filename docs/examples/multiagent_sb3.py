"""A policy from a common library in the multi-agent track: Stable-Baselines3's PPO as the global agent.

The four locals send the thesis's decision vectors (``reference-distributed``'s locals); the global
agent, the only learner, is an SB3 ``PPO`` policy on its own observation (the 19 message bits) and
action space (the 28 beliefs), trained on the PettingZoo ``ParallelEnv`` through a small Gymnasium
view of that one agent.  Any per-agent policy plugs in the same way: a dict of actions per step.

    python docs/examples/multiagent_sb3.py --timesteps 2048    # needs the train and multiagent extras
"""

import argparse

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO

from marine_fdi_env.baselines.reference_distributed_agent import DecisionVectorLocal
from marine_fdi_env.multiagent import LOCAL_AGENTS, parallel_env


class GlobalAgentView(gym.Env):
    """The ``global`` agent's view of the ParallelEnv, the locals playing fixed policies."""

    def __init__(self, **env_kwargs):
        self.env = parallel_env(message_budget="decision", **env_kwargs)
        self.locals = {a: DecisionVectorLocal(a) for a in LOCAL_AGENTS}
        self.observation_space = self.env.observation_space("global")
        self.action_space = self.env.action_space("global")

    def _actions(self, global_action):
        acts = {a: p.message(self.obs[a][None])[0].astype(np.int8) for a, p in self.locals.items()}
        acts["global"] = np.asarray(global_action, dtype=np.float32)
        return acts

    def reset(self, seed=None, options=None):
        self.obs, infos = self.env.reset(seed=seed, options=options)
        return self.obs["global"], infos["global"]

    def step(self, action):
        self.obs, rew, term, trunc, infos = self.env.step(self._actions(action))
        return self.obs["global"], rew["global"], term["global"], trunc["global"], infos["global"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--timesteps", type=int, default=2048)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    env = GlobalAgentView(scenario_config="default")
    model = PPO("MlpPolicy", env, n_steps=min(2048, args.timesteps), batch_size=64, seed=args.seed, verbose=0)
    model.learn(total_timesteps=args.timesteps)

    # one episode of the whole team, every agent acting through the ParallelEnv's dict API
    par = env.env
    obs, _ = par.reset(seed=10_000 + args.seed)  # an episode seed apart from the training episodes
    total = 0.0
    while par.agents:
        env.obs = obs
        action, _ = model.predict(obs["global"], deterministic=True)
        obs, rew, *_ = par.step(env._actions(action))
        total += rew["global"]
    print(f"team return {total:.1f} over one episode after {args.timesteps} PPO steps of the global agent")


if __name__ == "__main__":
    main()
