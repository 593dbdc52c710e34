"""The devkit's `input_representation.interface`: the three abstract parts of a model's input and
`InputRepresentation`, which makes the static layers and the agents and combines them (the devkit's classes, kept
so code that subclasses them runs unchanged)."""

from __future__ import annotations

import abc

import numpy as np


class StaticLayerRepresentation(abc.ABC):
    """Represents static map information as a numpy array."""

    @abc.abstractmethod
    def make_representation(self, instance_token: str, sample_token: str) -> np.ndarray:
        raise NotImplementedError()


class AgentRepresentation(abc.ABC):
    """Represents information of agents in scene as numpy array."""

    @abc.abstractmethod
    def make_representation(self, instance_token: str, sample_token: str) -> np.ndarray:
        raise NotImplementedError()


class Combinator(abc.ABC):
    """Combines the StaticLayer and Agent representations into a single one."""

    @abc.abstractmethod
    def combine(self, data: list[np.ndarray]) -> np.ndarray:
        raise NotImplementedError()


class InputRepresentation:
    """How a prediction model's input is made: the static layers, the agents, and how they are combined."""

    def __init__(self, static_layer: StaticLayerRepresentation, agent: AgentRepresentation, combinator: Combinator):
        self.static_layer_rasterizer = static_layer
        self.agent_rasterizer = agent
        self.combinator = combinator

    def make_input_representation(self, instance_token: str, sample_token: str) -> np.ndarray:
        static_layers = self.static_layer_rasterizer.make_representation(instance_token, sample_token)
        agents = self.agent_rasterizer.make_representation(instance_token, sample_token)
        return self.combinator.combine([static_layers, agents])
