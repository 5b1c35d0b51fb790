"""The co-occurrence cGAN's torch networks and the small tensor operations around them.

:func:`build_networks` makes the generator and the critic for a model's settings
(PSGAN-like, see :class:`tghop.cooc.model.CoocGAN`); :func:`average_step` is one update of
a weight average (the ``ema`` generator); :func:`split_tiles` / :func:`join_tiles` cut a
batch of ``t x t``-crop images into their crops and back (``tiles > 1``).

Every function takes the ``torch`` module as an argument or works on tensors it is given:
importing this module does not import PyTorch.
"""

from __future__ import annotations

from .._errors import TGHopError

__all__ = ["build_networks", "average_step", "split_tiles", "join_tiles"]


def average_step(torch, average, module, decay: float, step: int) -> None:
    """One bias-corrected update of a weight average after training step ``step`` (from 1).

    ``average <- beta average + (1 - beta) module`` for every parameter, with
    ``beta = decay (1 - decay**(step-1)) / (1 - decay**step)``: the average is then exactly
    the normalised mean of the weights after steps 1..step with weights
    ``decay**(step-i)``. Buffers (batch-norm statistics) are copied from ``module``.

    Parameters
    ----------
    torch : module
        The imported ``torch``.
    average : torch.nn.Module
        The weight average, updated in place; the same architecture as ``module``.
    module : torch.nn.Module
        The network just trained (read only).
    decay : float
        In [0, 1): the weight of the previous average (the model's ``ema``).
    step : int
        The training step just done, from 1 (step 1 copies ``module``: ``beta = 0``).
    """
    beta = decay * (1.0 - decay ** (step - 1)) / (1.0 - decay**step)
    with torch.no_grad():
        for avg, cur in zip(average.parameters(), module.parameters()):
            avg.mul_(beta).add_(cur, alpha=1.0 - beta)
        for avg, cur in zip(average.buffers(), module.buffers()):
            avg.copy_(cur)


def build_networks(torch, n_colours: int, n_cond: int, p: dict):
    """Generator and critic modules for settings ``p``, initialised as DCGAN / PSGAN do.

    Parameters
    ----------
    torch : module
        The imported ``torch``.
    n_colours : int
        Colour channels of the images (the exemplar's C: 1 or 3).
    n_cond : int
        Channels of the condition: ``k*k``, one per bin of a cell's co-occurrence matrix.
    p : dict
        Checked settings (:func:`tghop.cooc.config.check_settings`): ``n_layers``,
        ``g_widths`` and ``d_widths`` (``n_layers - 1`` entries each), ``noise_channels``,
        ``padding`` and ``kernel`` (default 5).

    Returns
    -------
    generator : torch.nn.Module
        ``generator(cond, noise)``: ``cond`` shape (m, n_cond, h, w), ``noise`` shape
        (m, noise_channels, h, w) -> images shape (m, n_colours, h * 2**n_layers,
        w * 2**n_layers) in [-1, 1] (tanh).
    critic : torch.nn.Module
        ``critic(x, cond)``: ``x`` shape (m, n_colours, H, W), ``cond`` shape
        (m, n_cond, h, w) -> shape (m,), one critic value per image.

    Raises
    ------
    TGHopError
        When ``g_widths`` or ``d_widths`` has not ``n_layers - 1`` entries.
    """
    nn = torch.nn
    n_layers = int(p["n_layers"])
    kernel = int(p.get("kernel", 5))

    class Generator(nn.Module):
        """``n_layers`` x (nearest upsampling x2, ``kernel`` x ``kernel`` conv with ``padding``,
        batch norm, ReLU); the last conv -> tanh."""

        def __init__(self):
            super().__init__()
            widths = list(p["g_widths"]) + [n_colours]
            layers, cin = [], n_cond + int(p["noise_channels"])
            for i, cout in enumerate(widths):
                layers += [nn.Upsample(scale_factor=2, mode="nearest"),
                           nn.Conv2d(cin, cout, kernel, padding=kernel // 2, padding_mode=p["padding"])]
                layers += [nn.BatchNorm2d(cout), nn.ReLU()] if i < len(widths) - 1 else [nn.Tanh()]
                cin = cout
            self.net = nn.Sequential(*layers)

        def forward(self, cond, noise):
            return self.net(torch.cat([cond, noise], dim=1))

    class Critic(nn.Module):
        """``n_layers`` ``kernel`` x ``kernel`` stride-2 convs (zero padding, leaky ReLU); the
        condition joins after the third."""

        def __init__(self):
            super().__init__()
            self.join = min(3, n_layers - 1)
            widths = list(p["d_widths"]) + [1]
            self.convs = nn.ModuleList()
            cin = n_colours
            for i, cout in enumerate(widths):
                if i == self.join:
                    cin += n_cond
                self.convs.append(nn.Conv2d(cin, cout, kernel, stride=2, padding=kernel // 2))
                cin = cout
            self.act = nn.LeakyReLU(0.2)

        def forward(self, x, cond):
            for i, conv in enumerate(self.convs):
                if i == self.join:
                    c = nn.functional.interpolate(cond, size=x.shape[-2:], mode="nearest")
                    x = torch.cat([x, c], dim=1)
                x = conv(x)
                if i < len(self.convs) - 1:
                    x = self.act(x)
            return x.mean((1, 2, 3))  # one critic value per crop (the map of a fully convolutional critic)

    if len(p["g_widths"]) != n_layers - 1 or len(p["d_widths"]) != n_layers - 1:
        raise TGHopError(f"g_widths and d_widths need n_layers - 1 = {n_layers - 1} entries each")
    gen, critic = Generator(), Critic()
    for module in list(gen.modules()) + list(critic.modules()):  # DCGAN / PSGAN initialisation
        if isinstance(module, nn.Conv2d):
            nn.init.normal_(module.weight, 0.0, 0.02)
            nn.init.zeros_(module.bias)
        elif isinstance(module, nn.BatchNorm2d):
            nn.init.normal_(module.weight, 1.0, 0.02)
            nn.init.zeros_(module.bias)
    return gen, critic


def split_tiles(x, t: int):
    """``(m, c, t*a, t*b)`` -> ``(m*t*t, c, a, b)``: each item's t x t tiles, row by row.

    Parameters
    ----------
    x : torch.Tensor, shape (m, c, t*a, t*b)
        A batch of images (or conditions) whose sides are multiples of ``t``.
    t : int
        Tiles per side; 1 returns ``x`` itself.

    Returns
    -------
    torch.Tensor, shape (m*t*t, c, a, b)
        Item ``i``'s tile ``(r, s)`` at index ``i*t*t + r*t + s``.
    """
    if t == 1:
        return x
    m, c, h, w = x.shape
    x = x.reshape(m, c, t, h // t, t, w // t).permute(0, 2, 4, 1, 3, 5)
    return x.reshape(m * t * t, c, h // t, w // t)


def join_tiles(x, t: int):
    """The inverse of :func:`split_tiles`: ``(m*t*t, c, a, b)`` -> ``(m, c, t*a, t*b)``.

    Parameters
    ----------
    x : torch.Tensor, shape (m*t*t, c, a, b)
        Tiles in :func:`split_tiles`' order.
    t : int
        Tiles per side; 1 returns ``x`` itself.

    Returns
    -------
    torch.Tensor, shape (m, c, t*a, t*b)
    """
    if t == 1:
        return x
    n, c, a, b = x.shape
    x = x.reshape(n // (t * t), t, t, c, a, b).permute(0, 3, 1, 4, 2, 5)
    return x.reshape(n // (t * t), c, t * a, t * b)

