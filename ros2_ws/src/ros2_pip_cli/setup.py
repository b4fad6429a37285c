from setuptools import find_packages, setup

package_name = "ros2_pip_cli"

# No console_scripts on purpose: the `ros2` launcher is written into the project's venv by
# scripts/setup.sh only, so a regular ROS 2 install never sees a second `ros2`.
setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm developers",
    maintainer_email="dev@example.com",
    description="The ros2 command for the pip install of ROS 2 (no ros2cli wheels exist).",
    license="Apache-2.0",
)
