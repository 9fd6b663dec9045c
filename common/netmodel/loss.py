"""Loss processes of a link: none, Bernoulli(p), or Gilbert-Elliott two-state bursts."""

from __future__ import annotations

from typing import Protocol

from common.config.network import LinkProfile


class LossProcess(Protocol):
    """Decides per message, in send order, whether it is lost, from two uniforms in [0, 1)."""

    def lost(self, u_state: float, u_loss: float) -> bool: ...


class NoLoss:
    """A link that loses nothing."""

    def lost(self, u_state: float, u_loss: float) -> bool:
        return False


class BernoulliLoss:
    """Independent losses with probability p (stateless: depends on the message's draw only)."""

    def __init__(self, p: float) -> None:
        self._p = p

    def lost(self, u_state: float, u_loss: float) -> bool:
        return u_loss < self._p


class GilbertElliottLoss:
    """Two-state Markov loss: the state steps once per message, then loses with h_state.

    Stationary P(bad) = p_gb / (p_gb + p_bg); stationary loss rate pi_G*h_G + pi_B*h_B.
    The first message draws its state from the stationary law, so statistics need no burn-in.
    """

    def __init__(self, *, p_gb: float, p_bg: float, loss_good: float, loss_bad: float) -> None:
        self._p_gb = p_gb
        self._p_bg = p_bg
        self._h_good = loss_good
        self._h_bad = loss_bad
        self.pi_bad = p_gb / (p_gb + p_bg)
        self.bad: bool | None = None  # None until the first message

    def lost(self, u_state: float, u_loss: float) -> bool:
        if self.bad is None:
            self.bad = u_state < self.pi_bad
        elif self.bad:
            self.bad = not (u_state < self._p_bg)
        else:
            self.bad = u_state < self._p_gb
        return u_loss < (self._h_bad if self.bad else self._h_good)


def make_loss(profile: LinkProfile) -> LossProcess:
    """The loss process a profile asks for (a fresh one: Gilbert-Elliott holds state)."""
    if profile.loss == "bernoulli":
        return BernoulliLoss(profile.loss_p)
    if profile.loss == "gilbert_elliott":
        return GilbertElliottLoss(
            p_gb=profile.ge_p_gb,
            p_bg=profile.ge_p_bg,
            loss_good=profile.ge_loss_good,
            loss_bad=profile.ge_loss_bad,
        )
    return NoLoss()
