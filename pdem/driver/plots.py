"""Plots the driver writes next to a run's data (matplotlib, Agg backend, PNG)."""
import numpy as np


def series_figure(h5_path, rows, cols, size):
    """(series dict, figure, axes) for a plot of the /series of a results file (Agg backend)."""
    import h5py
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with h5py.File(h5_path, "r") as f:
        s = {k: f["series"][k][...] for k in f["series"]}
    fig, ax = plt.subplots(rows, cols, figsize=size, sharex=True)
    return s, fig, ax


def save_figure(fig, png_path):
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(png_path, dpi=110)
    plt.close(fig)


def plot_energy(ax, t, ke):
    """Kinetic energy on a log axis, clipped 12 decades below its maximum (it starts at 0)."""
    ax.semilogy(t, np.maximum(ke, 1e-12 * max(float(ke.max()), 1e-300)))
    ax.set_ylabel("kinetic energy [J]")


def plot_series(results_path, png_path):
    s, fig, ax = series_figure(results_path, 2, 2, (10, 7))
    t = s["time"]
    plot_energy(ax[0, 0], t, s["kinetic_energy"])
    ax[0, 1].plot(t, s["contacts_per_particle"])
    ax[0, 1].set_ylabel("contacts per particle [-]")
    ax[1, 0].semilogy(t, np.maximum(s["unbalanced_force"], 1e-12))
    ax[1, 0].set_ylabel("unbalanced force ratio [-]")
    ax[1, 1].plot(t, s["floor_force_z"])
    ax[1, 1].set_ylabel("force on the floor, z [N]")
    for a in ax[1]:
        a.set_xlabel("time [s]")
    save_figure(fig, png_path)


