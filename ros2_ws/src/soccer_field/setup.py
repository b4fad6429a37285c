from setuptools import find_packages, setup

package_name = "soccer_field"

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
    description="The soccer field's dimensions (RoboCup Humanoid League KidSize), read by "
                "the simulator, the robot's behaviour and the debug GUI.",
    license="Apache-2.0",
)
