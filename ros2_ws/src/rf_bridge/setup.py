from setuptools import find_packages, setup

package_name = "rf_bridge"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm dev",
    maintainer_email="dev@example.com",
    description="RoboFrame-style messaging bridge: ROS 2 to ROS 1 and robot-to-robot links.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["rf_bridge = rf_bridge.adapters.ros2:main"],
        "efficient_comm.components": ["BridgeNode = rf_bridge.adapters.ros2:BridgeNode"],
    },
)
