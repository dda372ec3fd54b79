"""Installable package for SemanticFeels (neuralfeels_sem).

torch is deliberately not a hard requirement here: the Makefile installs the CPU
build torch==2.13.0 first, and a loose torch requirement would let pip pull a
multi-GB CUDA build on a fresh machine.
"""

from setuptools import find_packages, setup

INSTALL_REQUIRES = [
    "numpy>=1.26,<3",
    # Fused CPU kernels of the hash grid and its optimiser (fields/hash_kernels.py).
    "numba>=0.60",
    # numpy's BLAS threads follow the `threads` setting (utils/device.py).
    "threadpoolctl>=3.1",
    "scipy>=1.11",
    "hydra-core==1.3.8",
    "omegaconf>=2.3,<2.4",
    "hydra-joblib-launcher==1.2.0",
    "hydra-submitit-launcher==1.2.0",
    "mujoco>=3.2",
    "pyrender==0.1.45",
    "trimesh>=4.4",
    "rtree>=1.2",
    "scikit-image>=0.22",
    "efficientnet-pytorch==0.7.1",
    # CPU inference of the classifier and the tactile depth network (perception/onnx_cpu.py):
    # onnx for torch's exporter, onnxruntime to run the exported graph.
    "onnx>=1.16",
    "onnxruntime>=1.18",
    "pillow>=10",
    "matplotlib>=3.8",
    "tqdm>=4.66",
    "opencv-contrib-python-headless>=4.9",
    "python-can>=4.4",
    "dynamixel-sdk>=3.7",
    "pyserial>=3.5",
    # PyPI has RealSense wheels for x86-64 Linux and Windows only; elsewhere (a Jetson, an
    # Arm board) librealsense's Python bindings are built from source, and the rest installs.
    "pyrealsense2>=2.55; (sys_platform == 'linux' and platform_machine == 'x86_64')"
    " or sys_platform == 'win32'",
    "pyudev>=0.24",
]

EXTRAS = {
    "torch": ["torch==2.13.0"],
    "dev": ["pytest>=8", "pytest-timeout>=2.3", "pytest-xdist>=3.6", "ruff>=0.6"],
    "ray": ["hydra-ray-launcher==1.2.2"],
    # viz.live=rerun (viz/live.py); pinned to the minor version its logging API was written for.
    "live": ["rerun-sdk>=0.41,<0.42"],
}

setup(
    name="neuralfeels_sem",
    version="0.1.0",
    description="SemanticFeels: material mapping with vision and touch during in-hand manipulation",
    python_requires=">=3.10",
    packages=find_packages(include=["neuralfeels_sem", "neuralfeels_sem.*"]),
    include_package_data=True,
    package_data={"neuralfeels_sem": ["assets/**/*", "objects/examples/*"]},
    install_requires=INSTALL_REQUIRES,
    extras_require=EXTRAS,
)
